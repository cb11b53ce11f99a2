# Two entry points (see README): `make demo` runs the main job on the bundled default problem,
# `make test` runs the test suite. Both create .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
# .installed: the runtime (what `make demo` needs); .installed-dev: plus the dev extras (pytest,
# ruff, mypy, hypothesis, radon, mkdocs...) for `make test`, `make lint`, `make docs` and `make bench`.
STAMP := $(VENV)/.installed
DEV_STAMP := $(VENV)/.installed-dev
PROBLEM ?= problems/zk500_table6_seam.toml
OUT ?= out/demo

.PHONY: demo test lint docs bench clean

# The installs are quiet (their log goes to .venv/install.log, shown if one fails): pip's
# hundreds of lines buried the verdict of the first `make demo`.
LOG := $(VENV)/install.log

$(STAMP): pyproject.toml
	@echo "Setting up $(VENV) (first run only, about 3 minutes: numpy, scipy, casadi, pinocchio...; log in $(LOG))"
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip > $(LOG) 2>&1 || { tail -n 40 $(LOG); exit 1; }
	$(BIN)/pip install -q -e . >> $(LOG) 2>&1 || { tail -n 40 $(LOG); exit 1; }
	touch $(STAMP)
	@echo "Installed. Run the tool as $(BIN)/rfsw-plan, or 'source $(BIN)/activate' first."

$(DEV_STAMP): $(STAMP)
	@echo "Adding the dev extras (pytest, ruff, mypy...; log in $(LOG))"
	$(BIN)/pip install -q -e '.[dev]' >> $(LOG) 2>&1 || { tail -n 40 $(LOG); exit 1; }
	touch $(DEV_STAMP)

demo: $(STAMP)
	$(BIN)/rfsw-plan plan $(PROBLEM) -o $(OUT)

# The tests start the CLI in subprocesses: with bytecode written (as an installed package has
# it), each start does not compile rfsw_plan's sources again when PYTHONDONTWRITEBYTECODE is set.
test: $(DEV_STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest

lint: $(DEV_STAMP)
	$(BIN)/ruff check rfsw_plan tests examples benchmarks
	$(BIN)/mypy

# The manual (docs/, mkdocs.yml) with warnings as errors, into out/site; its CLI reference and
# API pages are generated from the argparse parser and the docstrings (docs/hooks/). mkdocs is a
# dev extra, so docs needs the dev stamp (after `make demo` alone, .venv had no mkdocs: issue 39).
docs: $(DEV_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

# Benchmarks print figures; they are never part of the tests. benchmark_commands.py times every
# command as a user runs it (median of 5 runs, the import floor, the ratios); give it
# --vs OTHER_CHECKOUT to compare two trees in one run.
bench: $(DEV_STAMP)
	$(BIN)/python benchmarks/benchmark_commands.py
	$(BIN)/python benchmarks/benchmark_foundation.py
	$(BIN)/python benchmarks/benchmark_planner.py
	$(BIN)/python benchmarks/benchmark_validate.py
	$(BIN)/python benchmarks/benchmark_compare.py
	$(BIN)/python benchmarks/benchmark_placement.py

clean:
	rm -rf $(VENV) out
