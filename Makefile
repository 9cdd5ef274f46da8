# One command sets everything up (a .venv with the package and its test tools) and runs.
PY ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: demo test test-slow bench bench-study paper horizon browser clean

# The stamp is touched last: an interrupted set-up (or compile) runs again next time.
$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test,stonesoup]"
	$(BIN)/sensorplan compile
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/sensorplan demo

# Opt-in, never run by demo or test: a headless Chromium for the report's browser test
# (installs the Debian package chromium with apt-get when root; without a browser that test
# skips with its reason). CI runs it first.
browser:
	-@bash scripts/ensure_chromium.sh

# Lint and type-check first (fast), then the suite; any failure stops it.
test: $(STAMP)
	$(BIN)/python -m ruff check src tests scripts benchmarks examples
	$(BIN)/python -m mypy src
	$(BIN)/python -m pytest

test-slow: $(STAMP)
	$(BIN)/python -m pytest -m slow

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_planning.py
	$(BIN)/python benchmarks/bench_brute_force.py
	$(BIN)/python benchmarks/bench_simulation.py

# The studies of docs/results.md (resumable: rerun after an interruption).
paper: $(STAMP)
	$(BIN)/sensorplan study studies/paper.toml --out runs/paper
	$(BIN)/sensorplan report runs/paper

horizon: $(STAMP)
	$(BIN)/sensorplan study studies/horizon.toml --out runs/horizon
	$(BIN)/sensorplan report runs/horizon

bench-study: $(STAMP)
	$(BIN)/python benchmarks/bench_study.py

clean:
	rm -rf $(VENV) out
