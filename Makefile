# Thin wrappers around the README's commands. `make setup` builds .venv from nothing.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SWEEPER := $(VENV)/.optuna-sweeper-1.3.0

# folders that exist in this checkout (pipelines/ appears with the DVC stages)
CODE   := $(wildcard src tests pipelines benchmarks)

.PHONY: setup blender postgres compiler browser studio tracking-server reproduce paper-table1 mocap-suite push pull demo test lint format benchmark clean

setup: $(STAMP) $(SWEEPER)

# torch==2.13.0 first: it is the CPU build already on disk; any other spec pulls CUDA.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

# hydra/sweeper=optuna: hydra-optuna-sweeper's metadata pins optuna<3 but its code runs on the
# Optuna 5 we use (tests/test_sweep_launchers.py), so --no-deps, after every other pip call
# (redone whenever $(STAMP) is), and nothing later resolves optuna again.
$(SWEEPER): $(STAMP)
	$(BIN)/pip install --quiet --no-deps hydra-optuna-sweeper==1.3.0
	touch $(SWEEPER)

# Blender (bpy 5.0.1 pins numpy<2) gets its own environment, .venv-blender, for the
# worker processes that evaluate Rigify and user .blend rigs.
# The script keeps its own stamp and returns at once when the environment is ready.
blender:
	bash scripts/setup_blender_env.sh

# PostgreSQL (initdb, pg_ctl) for the MLflow tracking server on a real database
# (scripts/tracking_server.sh); installed from Debian's packages when missing (needs root).
postgres:
	@ls /usr/lib/postgresql/*/bin/pg_ctl >/dev/null 2>&1 || command -v pg_ctl >/dev/null 2>&1 \
	  || { [ "$$(id -u)" = 0 ] && export DEBIAN_FRONTEND=noninteractive \
	       && { apt-get install -y -q postgresql || { apt-get update -q && apt-get install -y -q postgresql; }; }; } \
	  || { echo "PostgreSQL is missing: apt-get install postgresql (as root)" >&2; exit 1; }

# A C++ compiler for inductor, which compiles the rig pass of the joint-space fit
# (rigmap.rigs.engine.compiled); installed from Debian's packages when missing (needs root).
compiler:
	@command -v g++ >/dev/null 2>&1 \
	  || { [ "$$(id -u)" = 0 ] && export DEBIAN_FRONTEND=noninteractive \
	       && { apt-get install -y -q g++ || { apt-get update -q && apt-get install -y -q g++; }; }; } \
	  || { echo "A C++ compiler is missing: apt-get install g++ (as root)" >&2; exit 1; }

# Chromium for the studio's browser tests (Playwright drives it; its own browser download
# cannot be used here); installed from Debian's packages when missing (needs root).
browser:
	@command -v chromium >/dev/null 2>&1 \
	  || { [ "$$(id -u)" = 0 ] && export DEBIAN_FRONTEND=noninteractive \
	       && { apt-get install -y -q chromium || { apt-get update -q && apt-get install -y -q chromium; }; }; } \
	  || { echo "Chromium is missing: apt-get install chromium (as root)" >&2; exit 1; }

# MLflow on PostgreSQL on this machine (then: tracking=server, or MLFLOW_TRACKING_URI).
tracking-server: setup postgres
	bash scripts/tracking_server.sh start

# The main job: the quick replication of the paper's tables (dvc repro; reports/index.html).
# It needs both environments: the wolf's stages evaluate a Rigify rig in Blender workers.
# --jobs 2: independent stages two at a time; the ones that time methods run alone.
reproduce: setup blender compiler
	$(BIN)/rigmap reproduce --jobs 2

# Table 1 at the paper's budget for the quadruped and the biped (about 2 h on 2 cores, nearly
# all of it the two minibatch-8 networks) into paper-run/ and reports/paper/
paper-table1: setup
	BIN=$(BIN) scripts/paper_table1.sh

# Issue #37's real-mocap suite: every clip of ../shared/mocap/ mapped whole onto the biped
# (about 4 000 frames, 5-6 min on 2 cores: not part of the quick replication). Needs the
# biped's corpus and poses (dvc repro animate@biped pose@biped);
# reports/map_suite/biped.md and metrics/biped/map_suite/
mocap-suite: setup
	$(BIN)/python pipelines/map_suite.py rig=biped

# Share outputs through the default DVC remote (.dvc/config: <clone>/../rigmap-dvc-remote):
# `make push` after a run, `make pull` in another clone instead of recomputing.
push: setup
	$(BIN)/python -m rigmap.dvc_remote check push
	PATH=$(BIN):$$PATH $(BIN)/dvc push

pull: setup
	$(BIN)/python -m rigmap.dvc_remote check pull
	PATH=$(BIN):$$PATH $(BIN)/dvc pull

# The studio in the browser (rigmap studio: pose, play, review, edit) on the main job's data:
# open http://127.0.0.1:8081 (Pose, Play) or http://127.0.0.1:8080 (Review, Edit); Ctrl-C stops it.
studio: setup
	$(BIN)/rigmap studio

# A first look without running the pipeline: describe and render the built-in rigs.
demo: setup
	$(BIN)/rigmap rigs list
	$(BIN)/rigmap rigs describe quadruped
	$(BIN)/rigmap rigs render quadruped --out reports/figures/rigs/quadruped.png
	$(BIN)/rigmap rigs render biped --out reports/figures/rigs/biped.png

# The Blender backend's tests need .venv-blender too, the tracking tests PostgreSQL, the
# studio's Chromium:
# nothing is skipped for a missing environment. Two workers (pytest-xdist), one per core,
# each running whole test files (--dist loadfile: a file's module fixtures stay in one process).
test: setup blender postgres compiler browser
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

lint: setup
	$(BIN)/ruff check $(CODE)
	$(BIN)/ruff format --check $(CODE)

format: setup
	$(BIN)/ruff format $(CODE)
	$(BIN)/ruff check --fix $(CODE)

benchmark: setup
	$(BIN)/python benchmarks/rig_eval.py
	$(BIN)/python benchmarks/supersample.py
	$(BIN)/python benchmarks/regression.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
