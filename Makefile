# The two commands of the README: `make demo` and `make test`. Both build the virtual environment first.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEVKIT_STAMP := $(VENV)/.devkit

.PHONY: demo test test-capped bench clean venv docs mutation

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,ray]'
	touch $@

# nuscenes-devkit pins numpy<2; we install it without its pins (test-only reference implementation), and
# truckscenes-devkit the same way (its pypcd4 is in the test extra).
$(DEVKIT_STAMP): $(STAMP)
	$(BIN)/pip install --quiet --no-deps nuscenes-devkit==1.2.0
	$(BIN)/pip install --quiet --no-deps truckscenes-devkit==1.2.0
	touch $@

venv: $(DEVKIT_STAMP)

demo: $(STAMP)
	$(BIN)/python pipelines/demo.py --out demo-out

# Tests run on every core (up to 4): the suite is ~8 minutes on one core of the 2-core CI machine, ~4 on two.
# --dist loadgroup keeps the tests marked xdist_group("ray") on one worker: one local Ray session, not four.
# Where ../shared is present, a skipped parity/devkit test fails the run (tests/conftest.py, pytest_sessionfinish).
test: $(DEVKIT_STAMP)
	$(BIN)/python -m pytest -q -n auto --maxprocesses=4 --dist loadgroup

# Issue 27: the fuzz, fault and reader suites in an 8 GB address space (`ulimit -v 8000000`): every hostile input ends
# as a conversion or a clean refusal, never a traceback, a panic or a hang.
test-capped: $(DEVKIT_STAMP)
	bash -c 'ulimit -v 8000000 && $(BIN)/python -m pytest -q -n 2 tests/fuzz tests/conversion tests/sources'

# Mutation testing of the core modules (mutmut 3), group by group within a time budget each; see MUTATION.md.
# Not part of `make test`. MUTATION_ARGS, e.g. "geometry mosaic --budget-s 300", picks groups and the budget.
mutation: $(DEVKIT_STAMP)
	$(BIN)/pip install --quiet -e '.[test,mutation]'
	$(BIN)/python mutation/run.py $(MUTATION_ARGS)

bench: $(DEVKIT_STAMP)
	$(BIN)/python benchmarks/run_all.py

docs: $(STAMP)
	$(BIN)/python -m nuparquet.schemas --docs docs/schemas.md
	$(BIN)/python -m nuparquet.cli.reference --docs docs/cli.md

clean:
	rm -rf $(VENV) demo-out .mutation
