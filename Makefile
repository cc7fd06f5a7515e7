# skidbench: `make reproduce` and `make test` on a fresh machine (Python 3.11, pip, gcc).
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
WORKERS ?=

.PHONY: venv test test-all reproduce reproduce-quick reproduce-extended bench dashboard clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev,dask]'
	touch $(STAMP)

venv: $(STAMP)

# the tests run on every core (pytest-xdist; TEST_WORKERS=0 runs them in this process)
TEST_WORKERS ?= auto

test: $(STAMP)
	$(BIN)/python -m bench.cpu $(BIN)/python -m pytest -q -m "not slow" --benchmark-skip -n $(TEST_WORKERS)

test-all: $(STAMP)
	$(BIN)/python -m bench.cpu $(BIN)/python -m pytest -q --benchmark-skip -n $(TEST_WORKERS)

reproduce: $(STAMP)
	$(BIN)/skidbench reproduce --all $(if $(WORKERS),--workers $(WORKERS),)

reproduce-quick: $(STAMP)
	$(BIN)/skidbench reproduce --all --quick

# the studies beyond the papers' tables and headline claims (NEES null distribution, replication, ablations):
# results/extended/
reproduce-extended: $(STAMP)
	$(BIN)/skidbench reproduce --all --extended $(if $(WORKERS),--workers $(WORKERS),)

# the speed benchmarks (tests/bench, pytest-benchmark); each run appends one line (commit, date, CPU, per benchmark
# mean/stddev/rounds) to results/bench_history.jsonl, charted on the dashboard's speed page
bench: $(STAMP)
	@mkdir -p .benchmarks
	$(BIN)/python -m pytest tests/bench -q --benchmark-only --benchmark-json=.benchmarks/latest.json
	$(BIN)/python -m bench.report.bench_history .benchmarks/latest.json

dashboard: $(STAMP)
	$(BIN)/skidbench dashboard

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks
