PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench clean typecheck docs notebooks

$(BIN)/python:
	@command -v $(PY) >/dev/null 2>&1 || { echo "need $(PY) on PATH (or: make PY=python3)"; exit 2; }
	$(PY) -m venv $(VENV)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e ".[dev]"
	$(BIN)/sinslab compile
	@touch $(STAMP)

demo: $(STAMP)
	$(BIN)/sinslab demo --out runs

# two processes, each taking whole test files (module fixtures are made once, and the docs
# tests that share their runs stay in one process)
test: $(STAMP)
	$(BIN)/python -m pytest -x -p no:cacheprovider -n 2 --dist loadfile

bench: $(STAMP)
	$(BIN)/python benchmarks/speed.py

clean:
	rm -rf $(VENV) runs site

# the type checker over the modules mypy.ini lists (also run by make test)
typecheck: $(STAMP)
	$(BIN)/python -m mypy

# the documentation with the API reference into site/ (open site/index.html); warnings are errors
docs: $(STAMP)
	$(BIN)/python -m sphinx -b html -n -W --keep-going -q -d site/.doctrees docs site
	@echo "site/index.html"

# the notebooks of notebooks/ alone, each run top to bottom in a fresh kernel (make test runs them too)
notebooks: $(STAMP)
	$(BIN)/python -m pytest -x -p no:cacheprovider -m notebook tests/test_notebooks.py
