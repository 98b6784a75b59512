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

test: install-test
	$(VENV)/bin/lint-imports
	$(PY) -m pytest

bench: install
	command -v wrk >/dev/null || (apt-get update -q && apt-get install -y -q wrk)
	$(PY) -m benchmarks.api_load
	$(PY) -m benchmarks.lambert
	$(PY) -m benchmarks.reentry
	$(PY) -m benchmarks.midcourse
	$(PY) -m benchmarks.intercept
	$(PY) -m benchmarks.robust

clean:
	rm -rf $(VENV) var .pytest_cache
