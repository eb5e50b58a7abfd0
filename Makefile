# One entry point for newcomers and CI. `make test` is what CI runs (see .ci/run).
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: setup test test-core lint format build wheels demo bench clean

setup: $(STAMP)

$(STAMP): requirements-dev.txt tools/check_system.sh
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' || \
	  { echo "error: Python 3.11 is needed (bpy 5.0.1 is built for it); found $$($(PYTHON) --version 2>&1). Install python3.11 or set PYTHON=/path/to/python3.11" >&2; exit 1; }
	@tools/check_system.sh
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements-dev.txt
	@touch $(STAMP)
	@echo "setup: $(VENV) ready"

wheels: setup
	$(PY) tools/fetch_wheels.py

test: setup wheels
	$(PY) -m pytest

test-core: setup
	$(PY) -m pytest tests/core tests/cli -m "not blender"

lint: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: setup
	$(VENV)/bin/ruff check --fix .
	$(VENV)/bin/ruff format .

build: setup wheels
	$(PY) tools/build_extension.py --output-dir dist

demo: setup
	$(PY) -m btf_addon doctor
	$(PY) -m btf_addon render --demo -o out/demo.png --resolution 640x360 --lights 128

bench: setup
	$(PY) benchmarks/run_all.py

clean:
	rm -rf dist out .pytest_cache .ruff_cache
