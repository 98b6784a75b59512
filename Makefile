# trajlab: `make run` starts the embedded service, `make test` runs the whole suite.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# make run PORT=8001 (or TRAJLAB_PORT=8001 make run) when 8000 is taken
PORT   ?= $(or $(TRAJLAB_PORT),8000)

.PHONY: run test install install-test bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed pyproject.toml
	$(PY) -m pip install --quiet -e ".[test]"
	touch $@

install: $(VENV)/.installed
install-test: $(VENV)/.installed-test

run: install
	$(VENV)/bin/trajlab serve --port $(PORT)

# scripts/test-prerequisites.sh makes the machine's PostgreSQL, Redis and Debian's Chromium present
# (or stops naming the missing one); the suite ends with the time each marker took.
# make test PYTEST_ARGS="--random-order" shuffles the order (pytest-random-order; seed printed).
test: install-test
	scripts/test-prerequisites.sh
	$(VENV)/bin/lint-imports
	$(PY) -m pytest $(PYTEST_ARGS)

$(VENV)/.installed-bench: $(VENV)/.installed pyproject.toml
	$(PY) -m pip install --quiet -e ".[bench]"
	touch $@

# Every benchmark in its own process (benchmarks/run_all.py): one that fails or hangs (BENCH_TIMEOUT s)
# does not stop the others, whose figures land in benchmarks/results/latest.json; the closing table
# names what failed and the exit status is non-zero.  make bench BENCH=lambert,memory runs a subset.
BENCH_TIMEOUT ?= 3600
bench: $(VENV)/.installed-bench
	command -v wrk >/dev/null || (apt-get update -q && apt-get install -y -q wrk)
	$(PY) -m benchmarks.run_all --timeout $(BENCH_TIMEOUT) $(if $(BENCH),--only $(BENCH))

clean:
	rm -rf $(VENV) var .pytest_cache
