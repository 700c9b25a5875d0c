PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow docs bench paper validation validation-measure validation-bench validation-peers clean

$(BIN)/python:
	@command -v $(PY) >/dev/null 2>&1 || { echo "python3.11 not found; set PY=/path/to/python3.11"; exit 2; }
	$(PY) -m venv $(VENV)

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test,dask]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/hwid run configs/paper.yaml --out runs/paper

# the fast default (under 10 minutes on 2 cores); Monte Carlo and long end-to-end tests are marked slow
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist worksteal --durations=15 -m "not slow"

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist worksteal --durations=15 -m slow

DOCS_STAMP := $(VENV)/.installed-docs

$(DOCS_STAMP): $(STAMP) pyproject.toml
	$(BIN)/python -m pip install -q -e '.[docs]'
	touch $(DOCS_STAMP)

# the site in build/site; --strict: a broken link, a missing page or a stale config reference fails
docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_simulate.py

paper: $(STAMP)
	$(BIN)/python experiments/paper/run.py

# Every validation page's tables, written by the scripts that measure them (docs/validation/generated/,
# each stamped with its script, commit, date and machine): the Monte Carlo pages (the scripts' default
# run counts; the sweeps resume in a folder per commit), then the timings (only on a quiet machine)
# and the peers (in .venv-peers). The blind checks' table comes from
# experiments/diagnosis_blind/table.py after its runs (docs/validation/blind.md).
VALIDATION_RUNS := runs/validation/$(shell git rev-parse --short HEAD 2>/dev/null || echo unknown)

validation: validation-measure validation-bench validation-peers

validation-measure: $(STAMP)
	$(BIN)/python experiments/paper/run.py --write
	$(BIN)/python benchmarks/bench_stage2_efficiency.py --write
	$(BIN)/python experiments/noise_sweep/run.py --write --out $(VALIDATION_RUNS)/noise_sweep
	$(BIN)/python experiments/periods_sweep/run.py --write --out $(VALIDATION_RUNS)/periods_sweep
	$(BIN)/python experiments/interval_coverage/run.py --write
	$(BIN)/python experiments/rig_time/run.py --write

# timings under load are wrong: refused while the 1-minute load average is 1.5 or more
validation-bench: $(STAMP)
	@$(BIN)/python -c "import os, sys; l = os.getloadavg()[0]; sys.exit(0 if l < 1.5 else \
		f'load average {l:.2f} >= 1.5: the timings would be wrong; run make validation-bench on a quiet machine')"
	$(BIN)/python benchmarks/bench_simulate.py --write
	$(BIN)/python benchmarks/bench_whole.py --write
	$(BIN)/python benchmarks/bench_joint_fit.py --write
	$(BIN)/python benchmarks/bench_batch.py --write
	$(BIN)/python benchmarks/bench_recorded.py --write

validation-peers:
	@test -x .venv-peers/bin/python || { echo "no .venv-peers: python3.11 -m venv .venv-peers && .venv-peers/bin/pip install -e '.[peers]'"; exit 2; }
	.venv-peers/bin/python benchmarks/bench_peers.py --write

clean:
	rm -rf runs build *.egg-info .pytest_cache
