# Set-up and the two main jobs. Each target creates or reuses .venv/ at the repo root.
PYTHON ?= python3.11
VENV := .venv
STAMP := $(VENV)/.installed

.PHONY: setup test test-slow repro bench clean-venv

$(STAMP): pyproject.toml
	@test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet --upgrade pip
	$(VENV)/bin/python -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

setup: $(STAMP)  ## create or reuse .venv and install the project

test: $(STAMP)  ## the default test suite (what CI runs)
	$(VENV)/bin/python -m pytest -q

test-slow: $(STAMP)  ## the long tests, on purpose
	$(VENV)/bin/python -m pytest -q -m slow

repro: $(STAMP)  ## the full paper reproduction
	PATH=$(CURDIR)/$(VENV)/bin:$$PATH $(VENV)/bin/dvc repro

bench: $(STAMP)
	$(VENV)/bin/python -m blindspot.bench.dsp --threads 1

clean-venv:
	rm -rf $(VENV)
