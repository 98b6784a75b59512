# trajlab: `make run` starts the embedded service, `make test` runs the whole suite, `make check` the
# fast loop (lint, types, layering, unit tests without the long solves).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# make run PORT=8001 (or TRAJLAB_PORT=8001 make run) when 8000 is taken
PORT   ?= $(or $(TRAJLAB_PORT),8000)

# `make run` prints how long it took to the first /healthz (scripts/first_healthz.py)
MAKE_STARTED := $(shell date +%s.%N)

.PHONY: run test check lint install install-test bench clean lock guide

# Installs follow the lock, uv.lock: every transitive dependency at one version with its hashes, so two
# installs a month apart are the same.  uv (pinned) installs from it in seconds; uv reads PyPI only
# (never pip.conf's local indexes under /opt, which CI's machine has too).  --locked stops when
# pyproject.toml changed without `make lock`; --inexact leaves the other extras' packages (and uv) alone.
# Without uv (it could not be installed) pip installs the same versions from the lock's export,
# requirements/*.txt.
UV_VERSION := 0.13.9
UV := $(VENV)/bin/uv
UV_SYNC = UV_PROJECT_ENVIRONMENT=$(VENV) UV_PYTHON_DOWNLOADS=never $(UV) sync --locked --inexact --quiet
define install_locked
	if [ -x $(UV) ]; then $(UV_SYNC) $(1); \
	else $(PY) -m pip install --quiet -r requirements/$(2).txt && $(PY) -m pip install --quiet --no-deps -e .; fi
endef

$(VENV)/.installed: pyproject.toml uv.lock
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet uv==$(UV_VERSION) || echo "make: uv could not be installed; pip installs from requirements/*.txt (slower)" >&2
	$(call install_locked,,base)
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed pyproject.toml uv.lock
	$(call install_locked,--extra test,test)
	touch $@

# After a change of pyproject.toml's dependencies: re-resolve (from PyPI) and export for the pip path.
lock: $(VENV)/.installed
	$(UV) lock
	$(UV) export --quiet --frozen --no-emit-project --no-header -o requirements/base.txt
	$(UV) export --quiet --frozen --no-emit-project --no-header --extra test -o requirements/test.txt
	$(UV) export --quiet --frozen --no-emit-project --no-header --extra bench -o requirements/bench.txt

# The user guide (MkDocs, docs/ + mkdocs.yml) into app/static/guide, which the service serves at /guide.
# `make install` (so `make run`) builds it: the console, every failed job and the CLI link to /guide/, a 404
# on a fresh clone before (issue 38).  MkDocs is a base dependency for that; the build (~10 s of CPU, its
# hook imports the app for the API reference) runs again only when docs/, mkdocs.yml or the hook changed.
# The suite builds it too (tests/unit/test_docs_site.py, --strict).
GUIDE := app/static/guide/index.html
$(GUIDE): $(VENV)/.installed mkdocs.yml scripts/guide_hooks.py $(shell find docs -type f 2>/dev/null)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet -d app/static/guide
	touch $@

guide: $(VENV)/.installed
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet -d app/static/guide

install: $(VENV)/.installed $(GUIDE)
install-test: $(VENV)/.installed-test $(GUIDE)

run: install
	@$(PY) scripts/first_healthz.py --port $(PORT) --since $(MAKE_STARTED) &
	$(VENV)/bin/trajlab serve --port $(PORT)

# The machine-checked rules: ruff (lint), mypy (types) and import-linter (layers), each configured in
# pyproject.toml.  mypy's cache (.mypy_cache) makes a second run take seconds.
lint: install-test
	$(VENV)/bin/ruff check --quiet .
	$(VENV)/bin/mypy
	$(VENV)/bin/lint-imports

# scripts/test-prerequisites.sh makes the machine's PostgreSQL, Redis and Debian's Chromium present
# (or stops naming the missing one); the suite ends with the time each marker took.
# make test PYTEST_ARGS="--random-order" shuffles the order (pytest-random-order; seed printed).
# The suite runs in TEST_WORKERS processes (pytest-xdist; auto: one per core; 0: in this process alone),
# each test file whole in one of them (tests/conftest.py says why and which files go together).
TEST_WORKERS ?= auto
XDIST = -n $(TEST_WORKERS) --dist loadfile
test: install-test
	scripts/test-prerequisites.sh
	$(MAKE) --no-print-directory lint
	$(PY) -m pytest $(XDIST) $(PYTEST_ARGS)

# The fast loop before a commit (under 2 minutes): the lint above and the unit tests less the long solves
# (`slow`, which `make test` still runs); no PostgreSQL, Redis or browser needed.
CHECK_MARKERS := not slow and not integration and not browser and not faults
check: lint
	$(PY) -m pytest -q $(XDIST) tests/unit -m "$(CHECK_MARKERS)" $(PYTEST_ARGS)

$(VENV)/.installed-bench: $(VENV)/.installed pyproject.toml uv.lock
	$(call install_locked,--extra bench,bench)
	touch $@

# Every benchmark in its own process (benchmarks/run_all.py): one that fails or hangs (BENCH_TIMEOUT s)
# does not stop the others, whose figures land in benchmarks/results/latest.json; the closing table
# names what failed and the exit status is non-zero.  make bench BENCH=lambert,memory runs a subset.
BENCH_TIMEOUT ?= 3600
bench: $(VENV)/.installed-bench
	command -v wrk >/dev/null || (apt-get update -q && apt-get install -y -q wrk)
	$(PY) -m benchmarks.run_all --timeout $(BENCH_TIMEOUT) $(if $(BENCH),--only $(BENCH))

clean:
	rm -rf $(VENV) var .pytest_cache .mypy_cache .ruff_cache
