# Set-up and the two main jobs. Each target creates or reuses .venv/ at the repo root.
PYTHON ?= python3.11
VENV := .venv
STAMP := $(VENV)/.installed

.PHONY: help setup setup-cluster test test-slow test-cluster repro data bench lock clean-venv

help:  ## list the targets and what each does (also what a bare `make` does)
	@grep -hE '^[a-zA-Z_-]+:.*## ' $(MAKEFILE_LIST) \
	  | sed -E 's/^([a-zA-Z_-]+):.*## (.*)/  \1\t\2/' | expand -t 16

# The exact versions of requirements.lock first, then the project itself without resolving again:
# a fresh clone gets the environment the committed dvc.lock was made with.
$(STAMP): pyproject.toml requirements.lock
	@test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet --upgrade pip
	$(VENV)/bin/python -m pip install --quiet -r requirements.lock
	$(VENV)/bin/python -m pip install --quiet --no-deps -e '.[test]'
	@touch $(STAMP)

setup: $(STAMP)  ## create or reuse .venv and install the project

# The cluster pieces (Ray, submitit/SLURM and Optuna sweeps, the PostgreSQL MLflow server), never
# part of `make setup` or `make test`. --no-deps: requirements-cluster.lock is complete, and
# hydra-ray-launcher's cloudpickle<3 pin would otherwise downgrade requirements.lock's cloudpickle.
# PostgreSQL 15 and Chromium (for the MLflow UI and DVC plots tests, -m slow; they skip without
# it) come from the system: apt-get install postgresql chromium.
CLUSTER_STAMP := $(VENV)/.installed-cluster
$(CLUSTER_STAMP): $(STAMP) requirements-cluster.lock
	$(VENV)/bin/python -m pip install --quiet --no-deps -r requirements-cluster.lock
	@touch $(CLUSTER_STAMP)

setup-cluster: $(CLUSTER_STAMP)  ## add the cluster extra (Ray, submitit, Optuna, PostgreSQL driver)

test-cluster: $(CLUSTER_STAMP)  ## the scale-out tests: launchers, Optuna, Ray, PostgreSQL server, UI
	$(VENV)/bin/python -m pytest -q -m slow tests/pipeline/test_launchers.py \
	  tests/pipeline/test_ray_launcher.py tests/pipeline/test_tracking_server.py \
	  tests/pipeline/test_mlflow_ui.py

# One worker per core, one test file per worker at a time. --no-loadscope-reorder: xdist would
# otherwise hand out the files with the most tests first, and the pipeline test (two tests, most
# of one worker's time) last; tests/conftest.py puts it first instead (LONGEST_FIRST).
test: $(STAMP)  ## the default test suite (what CI runs), one worker per core
	$(VENV)/bin/python -m pytest -q -n auto --dist loadfile --no-loadscope-reorder

test-slow: $(STAMP)  ## the long tests, on purpose
	$(VENV)/bin/python -m pytest -q -m slow

# The outside data sets into ../shared (or BLINDSPOT_SHARED), at their pinned commits, sha256
# checked; `python -m blindspot data fetch --from DIR` copies from a local mirror instead.
data: $(STAMP)  ## fetch the outside data sets (ETH/UCY, real radar recordings); see `blindspot data list`
	$(VENV)/bin/python -m blindspot data fetch

repro: $(STAMP)  ## the full paper reproduction
	PATH=$(CURDIR)/$(VENV)/bin:$$PATH $(VENV)/bin/dvc repro

bench: $(STAMP)  ## speed of the detection chain on one frame, one thread
	$(VENV)/bin/python -m blindspot.bench.dsp --threads 1

LOCK_VENV := .lock-venv
lock:  ## re-resolve requirements.lock from pyproject.toml in a throwaway venv
	rm -rf $(LOCK_VENV) && $(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(LOCK_VENV)/bin/python -m pip install --quiet -e '.[test]'
	{ sed -n '1,3p' requirements.lock; $(LOCK_VENV)/bin/python -m pip freeze --exclude-editable \
	  | sed 's/^torch==\(.*\)+cpu$$/torch==\1/'; } > requirements.lock.new
	mv requirements.lock.new requirements.lock && rm -rf $(LOCK_VENV)

clean-venv:  ## remove .venv
	rm -rf $(VENV)
