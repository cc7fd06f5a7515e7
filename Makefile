# skidbench: `make reproduce` and `make test` on a fresh machine (Python 3.11, pip, gcc).
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
WORKERS ?=

.PHONY: venv test test-all reproduce reproduce-quick bench dashboard clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev,dask]'
	touch $(STAMP)

venv: $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow" --benchmark-skip

test-all: $(STAMP)
	$(BIN)/python -m pytest -q --benchmark-skip

reproduce: $(STAMP)
	$(BIN)/skidbench reproduce --all $(if $(WORKERS),--workers $(WORKERS),)

reproduce-quick: $(STAMP)
	$(BIN)/skidbench reproduce --all --quick

bench: $(STAMP)
	$(BIN)/python -m pytest tests/bench -q --benchmark-only --benchmark-json=.benchmarks/latest.json

dashboard: $(STAMP)
	$(BIN)/skidbench dashboard

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks
