# Quick start: `make run` (set up + run the default pipeline), `make test` (set up + run the tests).
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= egl
# Stages call `python`: make it the project environment's.
export PATH := $(abspath $(BIN)):$(PATH)

.PHONY: setup run test lint params bench results gallery clean-venv

setup: $(STAMP)

# MuJoCo renders off-screen through libEGL and the TO compiles C with gcc (tcc, if there, for
# -O0 builds), which fresh Debian images may lack; everything else is on PyPI.
$(STAMP): pyproject.toml requirements.lock
	@(ldconfig -p | grep -q 'libEGL.so.1' && command -v gcc >/dev/null) || bash .ci/install-system-deps
	@command -v tcc >/dev/null || bash .ci/install-system-deps || echo "locoman: no tcc; the TO's -O0 builds use gcc"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -c requirements.lock -e ".[dev]"
	@[ -d .dvc ] || $(BIN)/dvc init -q
	touch $(STAMP)

# The learned backends (torch, diffusers, transformers) are not in the default install, but the
# tests run each of them on small models they build.
LEARNED := $(VENV)/.installed-learned
$(LEARNED): $(STAMP)
	$(BIN)/python -m pip install -q -c requirements.lock -e ".[dev,learned]"
	touch $(LEARNED)

# The DAG in two arms at once, one per core (`locoman/repro.py` says why it is done this way).
# Arm 1: `tiny` to its solve, which compiles the G1's terms for every solve after it, then
# `tiny`'s figures (two grid jobs, about 8 min; the longest item, its naive Fig. 5 cell, about
# 4), its evaluation and paper B. Arm 2: S1's and S2's perception and keyframes meanwhile,
# then (`after:`) their solves, evaluations and executions (S2's solve, about 5 min, the
# longest stage).
INPUTS := scene generate masks clouds contacts retarget
ARM_TINY := validate $(INPUTS:%=%@tiny) solve@tiny figures@tiny evaluate@tiny execute@tiny \
	scene@mm_pick_place demos kmp_fit hqp_replay
ARM_REST := after:validate $(INPUTS:%=%@s1_basket) $(INPUTS:%=%@s2_trolley) after:solve@tiny \
	solve@s1_basket evaluate@s1_basket execute@s1_basket solve@s2_trolley evaluate@s2_trolley \
	execute@s2_trolley

run: setup
	$(BIN)/python -m locoman.repro "$(ARM_TINY)" "$(ARM_REST)"

# Two pytest-xdist workers, a test file on one: the end-to-end file (tiny's DVC subgraph, then
# grid cells on its artifacts, in order) starts on one, the DVC experiments on the other, and
# the other files fill in on whichever is free (tests/conftest.py orders them); a plain
# `pytest` runs them all in one process.
TEST_JOBS ?= 2
test: setup $(LEARNED)
	$(BIN)/python -m pytest -q -n $(TEST_JOBS) --dist loadfile --no-loadscope-reorder

# The headline numbers per scenario, one table (from the stages' metrics.json).
results: setup
	$(BIN)/python -m locoman.results

# The README's pictures (docs/gallery/) from the pipeline's outputs: after `make run`.
gallery: setup
	$(BIN)/python -m locoman.gallery

lint: setup
	$(BIN)/ruff check . && $(BIN)/ruff format --check .

# Speed figures (JSON), outside the test suite.
bench: setup
	$(BIN)/dvc repro kmp_fit
	$(BIN)/python benchmarks/mm_branch.py
	$(BIN)/dvc repro scene
	$(BIN)/python benchmarks/perception.py
	$(BIN)/dvc repro retarget
	$(BIN)/python benchmarks/retarget_speed.py
	$(BIN)/dvc repro retarget@tiny
	$(BIN)/python benchmarks/to_solvers.py
	$(BIN)/dvc repro solve
	$(BIN)/python benchmarks/execute_step.py

# Recompose params.yaml from conf/ (the same composition `dvc exp run -S` performs).
params: setup
	$(BIN)/python -m locoman.config.compose

clean-venv:
	rm -rf $(VENV)
