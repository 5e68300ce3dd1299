# PlateLight: the two commands a new machine needs are `make demo` and `make test`.
# Both create the pinned virtual environment (.venv) first and install missing system packages.
SHELL := /bin/bash
PY_SYS ?= $(shell command -v python3.11 || echo python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.platelight-stamp
OUT ?= out/demo
PYTEST_ARGS ?=

.PHONY: venv test test-fast demo bench dist validate clean

venv: $(STAMP)

$(STAMP): requirements.txt
	@$(PY_SYS) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else "bpy 5.0.1 needs Python 3.11; set PY_SYS=/path/to/python3.11")'
	test -x $(PY) || $(PY_SYS) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -r requirements.txt
	bash tools/ensure-system-deps.sh $(VENV)
	# `python -m platelight` from any folder: the checkout itself is the package. The site folder
	# is asked for in the shell: make expands a recipe before running its first line (no venv yet).
	site=$$($(PY) -c "import sysconfig; print(sysconfig.get_paths()['purelib'])") && \
	  test -n "$$site" && ln -sfn "$(CURDIR)" "$$site/platelight"
	touch $(STAMP)

test: venv
	$(PY) -m pytest tests $(PYTEST_ARGS)

# Engine-only tests (no Blender), for a quick loop.
test-fast: venv
	$(PY) -m pytest tests -m "not blender" $(PYTEST_ARGS)

demo: venv
	$(PY) -m platelight demo --out $(OUT)

bench: venv
	$(PY) tests/bench/run_all.py --out docs/bench

validate: venv
	$(PY) tools/extension.py validate

dist: venv
	$(PY) tools/extension.py build --out dist

clean:
	rm -rf build dist out bench_out
