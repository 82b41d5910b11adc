# The two front-door commands: `make demo` and `make test`. Each sets everything up on a fresh
# machine (virtual environment + install from pyproject.toml) before it runs.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_OUT ?= demo-out

.PHONY: demo test test-fast bench lint check-wheel clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	bash scripts/demo.sh $(BIN)/simcred $(DEMO_OUT)

# One BLAS thread: the statistical suites multiply many small matrices, which OpenBLAS's threads
# make 3-5x slower on 2 cores (results are identical either way). TEST_WORKERS pytest processes
# (pytest-xdist) share the tests; each test's result does not depend on which runs it.
TEST_WORKERS ?= 2
test: $(STAMP)
	bash scripts/ensure_chromium.sh
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -n $(TEST_WORKERS)

test-fast: $(STAMP)
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -n $(TEST_WORKERS) -m "not slow"

bench: $(STAMP)
	$(BIN)/python benchmarks/compare.py
	$(BIN)/python benchmarks/sim.py
	$(BIN)/python benchmarks/contracts.py
	$(BIN)/python benchmarks/reprocess.py
	$(BIN)/python benchmarks/vary.py
	$(BIN)/python benchmarks/sumo.py
	$(BIN)/python benchmarks/response.py

# pip install . (not editable) into a fresh venv; paper all + validate from outside the repo.
check-wheel:
	PYTHON=$(PYTHON) bash scripts/check_wheel_install.sh

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache .hypothesis
