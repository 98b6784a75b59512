# trajlab: `make run` starts the embedded service, `make test` runs the whole suite.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python

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
	$(VENV)/bin/trajlab serve

test: install-test
	$(PY) -m pytest

bench: install
	$(PY) -m benchmarks.lambert
	$(PY) -m benchmarks.reentry
	$(PY) -m benchmarks.midcourse
	$(PY) -m benchmarks.intercept
	$(PY) -m benchmarks.robust

clean:
	rm -rf $(VENV) var .pytest_cache
