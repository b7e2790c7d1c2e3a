PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
LINT_PATHS := src tests benchmarks

.PHONY: demo test bench lint clean

$(STAMP): pyproject.toml
	@echo 'fuzzypos: creating $(VENV) and installing fuzzypos and its dependencies (a few minutes, once)'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,lint]'
	$(BIN)/python -m pip install --quiet -e '.[graph]' || echo 'no gtsam wheel for this Python: the loop-closure tests skip'
	$(BIN)/python -m pip install --quiet -e '.[ray]' || echo 'no ray wheel for this Python: fuzzypos batch and its tests skip'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/fuzzypos demo

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 $(BIN)/python benchmarks/bench_pipeline.py

# ruff (lint and format check) over the code, mypy over src/ (files and settings: pyproject.toml)
lint: $(STAMP)
	$(BIN)/ruff check $(LINT_PATHS)
	$(BIN)/ruff format --check $(LINT_PATHS)
	$(BIN)/mypy

clean:
	rm -rf $(VENV) demo-output .pytest_cache .mypy_cache .ruff_cache
