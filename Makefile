# PlateLight: the two commands a new machine needs are `make demo` and `make test`.
# Both create the pinned virtual environment (.venv) first and install missing system packages.
SHELL := /bin/bash
# BLENDER picks the Blender release the suite runs on (requirements/blender-X.Y.txt); 5.2 LTS is
# the default. Each release has its own virtual environment: .venv for the default, .venv-X.Y else.
BLENDER ?= 5.2
REQUIREMENTS := requirements/blender-$(BLENDER).txt
# The Python the release's bpy wheel is built for, from the first line of its requirements file.
PY_VERSION := $(shell sed -n '1s/.*built for Python \([0-9]*\.[0-9]*\).*/\1/p' $(REQUIREMENTS) 2>/dev/null)
# Wheels whose metadata conflicts with the release's pins but that run there (see the file).
NO_DEPS := $(wildcard requirements/blender-$(BLENDER)-no-deps.txt)
VENV ?= $(if $(filter 5.2,$(BLENDER)),.venv,.venv-$(BLENDER))
PY := $(VENV)/bin/python
STAMP := $(VENV)/.platelight-stamp
OUT ?= out/demo
PYTEST_ARGS ?=
# The suite runs in this many processes (pytest-xdist); each test has its own profile and folder.
TEST_JOBS ?= $(shell nproc 2>/dev/null || echo 2)

.PHONY: venv test test-fast demo bench bench-960 bench-1080 bench-gpu bench-shot bench-motion bench-shapes bench-shot-gpu dist validate clean

venv: $(STAMP)

$(STAMP): $(wildcard $(REQUIREMENTS)) $(NO_DEPS)
	@test -f $(REQUIREMENTS) || { echo "No $(REQUIREMENTS): BLENDER must be one of $$(ls requirements | sed -n 's/^blender-\([0-9.]*\)\.txt$$/\1/p' | xargs)" >&2; exit 1; }
	test -x $(PY) || $${PY_SYS:-$$(bash tools/find-python.sh $(PY_VERSION))} -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -r $(REQUIREMENTS)
	$(if $(NO_DEPS),$(PY) -m pip install -q --disable-pip-version-check --no-deps -r $(NO_DEPS))
	bash tools/ensure-system-deps.sh $(VENV)
	# `python -m platelight` from any folder: the checkout itself is the package. The site folder
	# is asked for in the shell: make expands a recipe before running its first line (no venv yet).
	site=$$($(PY) -c "import sysconfig; print(sysconfig.get_paths()['purelib'])") && \
	  test -n "$$site" && ln -sfn "$(CURDIR)" "$$site/platelight"
	touch $(STAMP)

test: venv
	$(PY) -m pytest tests -n $(TEST_JOBS) --dist worksteal $(PYTEST_ARGS)

# Engine-only tests (no Blender), for a quick loop.
test-fast: venv
	$(PY) -m pytest tests -m "not blender" -n $(TEST_JOBS) --dist worksteal $(PYTEST_ARGS)

demo: venv
	$(PY) -m platelight demo --out $(OUT)

bench: venv
	$(PY) tests/bench/run_all.py --out docs/bench

# the compositing benchmark at production sizes (long: truths at 512 spp, cached in bench_out/)
bench-960: venv
	PLATELIGHT_BENCH_SIZE=960x540 $(PY) tests/bench/run_all.py --out docs/bench --only composite

bench-1080: venv
	PLATELIGHT_BENCH_SIZE=1920x1080 $(PY) tests/bench/run_all.py --out docs/bench --only composite

# Cycles on the GPU and EEVEE on a real GPU; stops with one sentence where Cycles finds no GPU
bench-gpu: venv
	PLATELIGHT_BENCH_DEVICE=GPU PLATELIGHT_BENCH_SIZE=960x540 $(PY) tests/bench/run_all.py --out docs/bench --only composite

# the shot benchmark against a skilled user's shadow catcher, one invocation (long: about 3 hours
# of truths per scene at 960x540 on 2 cores, cached in bench_out/shot/)
bench-shot: venv
	PLATELIGHT_BENCH_SIZE=$${PLATELIGHT_BENCH_SIZE:-960x540} $(PY) tests/bench/bench_shot.py

bench-motion: venv
	PLATELIGHT_BENCH_NAME=motion PLATELIGHT_BENCH_SIZE=$${PLATELIGHT_BENCH_SIZE:-960x540} $(PY) tests/bench/bench_shot.py

# the shapes a probe at the centre cannot shade: a turning Suzanne, a bending column, and the
# convex rolling sphere (docs/bench/motion_shapes_320x180.md; about an hour on 2 cores)
bench-shapes: venv
	PLATELIGHT_BENCH_SCENES='turning Suzanne, hard sun, photo floor, textured;bending column, city, grey floor, diffuse;rolling, hard sun, photo floor, diffuse' \
	PLATELIGHT_BENCH_NAME=motion_shapes PLATELIGHT_BENCH_SIZE=$${PLATELIGHT_BENCH_SIZE:-320x180} PLATELIGHT_BENCH_TRUTH_HALF_SPP=512 \
	PLATELIGHT_BENCH_CATCHER_SPP=4,16,64 PLATELIGHT_BENCH_CG_SPP=4,16 PLATELIGHT_BENCH_ROUTES=platelight,sbrdf_self_shadowing,catcher \
	$(PY) tests/bench/bench_shot.py

bench-shot-gpu: venv
	PLATELIGHT_BENCH_DEVICE=GPU PLATELIGHT_BENCH_SIZE=$${PLATELIGHT_BENCH_SIZE:-960x540} $(PY) tests/bench/bench_shot.py

validate: venv
	$(PY) tools/extension.py validate

dist: venv
	$(PY) tools/extension.py build --out dist

clean:
	rm -rf build dist out bench_out
