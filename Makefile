# One entry point for newcomers and CI. `make test` is what CI runs (see .ci/run).
SHELL := /bin/bash

# The Blenders the extension supports and CI tests (README, "Blender versions"). 5.0 is the main
# development environment (.venv); each other version gets its own environment, created from the
# pinned requirements/blender-X.Y.txt, in .venvs/blender-X.Y.
BLENDERS := 4.2 4.5 5.0 5.3
MAIN_BLENDER := 5.0
# The Blender-facing tests: install the built zip, F12, viewport drawing, Cycles comparisons.
BLENDER_TESTS := tests/blender
# Where the whole suite runs. On 4.2/4.5 the CLI tests (bpy imported as a plain Python module, as
# `python -m btf_addon render` does) cannot: bpy 4.2 segfaults and bpy 4.5 hangs when the Python
# process exits after registering the add-on from the checkout. The Blender tests, which install
# the zip as Blender does, exit cleanly on both.
FULL_SUITE_BLENDERS := 5.0 5.3

PYTHON ?= $(shell command -v python3.11 || command -v python3)
# Blender 5.1+ runs Python 3.13. pyenv's shim answers `python3.13` only where 3.13 is selected,
# so the first candidate that really runs is taken, by its own sys.executable.
PYTHON313 ?= $(shell for p in python3.13 $(wildcard $(HOME)/.pyenv/versions/3.13*/bin/python3.13); \
  do $$p -c 'import sys; print(sys.executable)' 2>/dev/null && break; done)
# Wheels downloaded once and shared by every environment (pip installs from here).
WHEELHOUSE := .whl

MAIN_VENV := .venv
VENV := $(MAIN_VENV)
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

# `make test BLENDER=4.2` (or setup, build, …) works against that version's environment.
ifdef BLENDER
ifeq ($(filter $(BLENDER),$(BLENDERS)),)
$(error BLENDER=$(BLENDER) is not one of the tested versions: $(BLENDERS))
endif
ifneq ($(BLENDER),$(MAIN_BLENDER))
VENV := .venvs/blender-$(BLENDER)
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
endif
endif

.PHONY: setup test test-core test-blenders test-one lint format build wheels demo bench clean

setup: $(STAMP)

# venv_install(python, venv, requirements): a fresh venv holding exactly the pinned requirements.
# `pip download` fetches into the shared wheelhouse only what is not there yet; the install then
# reads only the wheelhouse, so the environments share every download.
define venv_install
	@tools/check_system.sh
	rm -rf $(2)
	$(1) -m venv $(2)
	$(2)/bin/python -m pip install -q --upgrade pip
	$(2)/bin/python -m pip download -q -d $(WHEELHOUSE) -r $(3)
	$(2)/bin/python -m pip install -q --no-index --find-links $(WHEELHOUSE) -r $(3)
	@touch $(2)/.installed
	@echo "setup: $(2) ready ($$($(2)/bin/python -c 'import bpy; print("Blender", bpy.app.version_string)'))"
endef

$(MAIN_VENV)/.installed: requirements-dev.txt requirements/common.txt tools/check_system.sh
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' || \
	  { echo "error: Python 3.11 is needed (bpy 5.0.1 is built for it); found $$($(PYTHON) --version 2>&1). Install python3.11 or set PYTHON=/path/to/python3.11" >&2; exit 1; }
	$(call venv_install,$(PYTHON),$(MAIN_VENV),requirements-dev.txt)

.venvs/blender-4.2/.installed .venvs/blender-4.5/.installed: .venvs/blender-%/.installed: requirements/blender-%.txt requirements/common.txt tools/check_system.sh
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' || \
	  { echo "error: Blender $* runs Python 3.11; set PYTHON=/path/to/python3.11" >&2; exit 1; }
	$(call venv_install,$(PYTHON),.venvs/blender-$*,requirements/blender-$*.txt)

.venvs/blender-5.3/.installed: requirements/blender-5.3.txt requirements/common.txt tools/check_system.sh
	@[ -n "$(PYTHON313)" ] || \
	  { echo "error: Blender 5.3 runs Python 3.13, not found; install it or set PYTHON313=/path/to/python3.13" >&2; exit 1; }
	$(call venv_install,$(PYTHON313),.venvs/blender-5.3,requirements/blender-5.3.txt)

wheels: setup
	$(PY) tools/fetch_wheels.py

# Without BLENDER: the whole suite on 5.0 (numpy 1.26) and on 5.3 (Python 3.13, numpy 2), then the
# Blender-facing tests on the LTS releases. With BLENDER=X.Y: the same for that one version.
# Each version's output starts with a "== Blender X.Y ==" banner; a summary line per version ends.
ifdef BLENDER
PYTEST_ARGS ?= $(if $(filter $(BLENDER),$(FULL_SUITE_BLENDERS)),,$(BLENDER_TESTS))
test: setup wheels
	@echo "== Blender $(BLENDER) ($$($(PY) -c 'import bpy, sys; print(bpy.app.version_string, "on Python", sys.version.split()[0])')) =="
	$(PY) -m pytest $(PYTEST_ARGS)
else
test:
	@tools/test_versions.sh "5.0 5.3:all 4.2:$(BLENDER_TESTS) 4.5:$(BLENDER_TESTS)"
endif

# The Blender-facing tests on every version (the full suites are `make test`).
test-blenders:
	@tools/test_versions.sh "$(foreach v,$(BLENDERS),$(v):$(BLENDER_TESTS))"

test-core: setup
	$(PY) -m pytest tests/core tests/cli -m "not blender"

# Ruff lives in the main environment only: linting does not depend on the Blender version.
lint: $(MAIN_VENV)/.installed
	$(MAIN_VENV)/bin/ruff check .
	$(MAIN_VENV)/bin/ruff format --check .

format: $(MAIN_VENV)/.installed
	$(MAIN_VENV)/bin/ruff check --fix .
	$(MAIN_VENV)/bin/ruff format .

build: setup wheels
	$(PY) tools/build_extension.py --output-dir dist

demo: setup
	$(PY) -m btf_addon doctor
	$(PY) -m btf_addon render --demo -o out/demo.png --resolution 640x360 --lights 128

bench: setup
	$(PY) benchmarks/run_all.py

clean:
	rm -rf dist out .pytest_cache .ruff_cache
