# The two commands of the README: `make demo` (install + run the main job on the mock arm)
# and `make test` (install + run the whole test suite). Both create ./.venv on first use.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: install bytecode demo typecheck test soak soak-serve chromium bench clean

# The suite runs on PYTEST_WORKERS xdist workers (`--dist loadgroup`: tests marked
# xdist_group("name") share a worker); it prints the 25 slowest tests at the end of every run,
# then its wall and CPU time. A crashed worker, a hung test or a hung worker ends the run
# (tests/support/watchdog.py). Four workers on two cores: the stand-in group holds one worker for
# ~6 minutes of trials on the clock, and other tests wait on pages and processes; with three the
# cores were busy ~90 % of the run, with four ~99 % (docs/testing.md, "Where the time goes").
PYTEST_WORKERS ?= 4
PYTEST_ARGS ?=
# `make soak`: the browser, rehearsal, rig-process and kill tests SOAK_RUNS times beside
# SOAK_HOGS busy cores (not in CI).
SOAK_RUNS ?= 10
SOAK_HOGS ?= 1
# SOAK_UNTIL=HH:MM: start no soak run that would not end by then (report the runs made);
# SOAK_STRESS_CYCLES: each lifetime stress test's cycles, run once before the soak runs (0: none)
SOAK_UNTIL ?=
SOAK_STRESS_CYCLES ?= 500

install: $(VENV)/.installed

# uv (from the package index) installs: it downloads and unpacks in parallel, where pip took ~2 of
# CI's minutes. uv does not read pip's configuration, so pip's find-links folders, constraint files
# and certificate bundle (where the machine sets them, e.g. a local CPU torch and a cap on torch) are
# passed on; they are read with $(PYTHON)'s pip: make expands a recipe before its first line creates
# the venv.
# It compiles no bytecode: `make bytecode` compiles what the suite imports (a quarter of the files,
# in 19 of the 48 s that compiling all of them took at install on 2 cores).
pip_setting = $(shell $(PYTHON) -m pip config list 2>/dev/null | sed -n "s/^[^.]*\.$(1)='\(.*\)'$$/\1/p" | head -1)
UV_INSTALL = $(addprefix SSL_CERT_FILE=,$(call pip_setting,cert)) \
	$(BIN)/uv pip install --quiet --python $(BIN)/python \
	$(addprefix --find-links ,$(call pip_setting,find-links)) \
	$(addprefix --constraint ,$(call pip_setting,constraint))

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet uv
	@# A torch wheel that the machine provides locally (pip's find-links, e.g. a CPU build) is
	@# installed first; elsewhere this step finds nothing and the registry's torch is used.
	-$(UV_INSTALL) --no-index --no-deps torch
	$(UV_INSTALL) -e '.[dev]'
	touch $@

# The validation is blind (the dashboard hides which trial of a pair is θ*); pilots add --unblind.
demo: install
	$(BIN)/handover serve --study ./study

# The browser tests drive Debian's Chromium through Playwright (which cannot download its own
# browsers here); installed once with apt-get when missing.
chromium:
	@if [ ! -x /usr/bin/chromium ]; then \
		export DEBIAN_FRONTEND=noninteractive; \
		apt-get update -qq >/dev/null && \
		apt-get install -y -qq -o DPkg::Lock::Timeout=600 chromium >/dev/null; \
	fi

# Where PYTHONDONTWRITEBYTECODE is set (it is here) no process writes a .pyc, and every process of the
# suite would compile torch, viser and the project from source: .ci/bytecode.py imports what the
# suite imports with it cleared, and the suite runs with it cleared (a module imported only later is
# compiled once, not by every process that imports it).
bytecode: install
	$(BIN)/python .ci/bytecode.py

# mypy checks the packages pyproject's [tool.mypy] files lists: ~75 s on a fresh clone here (40 CPU-s,
# most of it reading torch's and botorch's own annotations), ~2 s again with its cache (.mypy_cache).
typecheck: install
	$(BIN)/mypy

# mypy (one process, ~10 s on a fresh clone) runs beside `make bytecode` (two), not after it: on two
# cores the two steps took ~19 s one after the other. pytest runs through .ci/timed.py, which
# prints its wall and CPU time at the end, with the calibration loop's CPU time (how fast the
# machine was at the time).
test: install chromium
	$(BIN)/ruff check .
	$(MAKE) --no-print-directory --jobs=2 --output-sync=target bytecode typecheck
	PYTHONDONTWRITEBYTECODE= $(BIN)/python .ci/timed.py \
		$(BIN)/pytest -n $(PYTEST_WORKERS) --dist loadgroup --durations=25 $(PYTEST_ARGS)

soak: install chromium bytecode
	PYTHONDONTWRITEBYTECODE= $(BIN)/python .ci/soak.py --runs $(SOAK_RUNS) --hogs $(SOAK_HOGS) --workers $(PYTEST_WORKERS) --stress-cycles $(SOAK_STRESS_CYCLES) $(if $(SOAK_UNTIL),--until $(SOAK_UNTIL))

# `make soak-serve`: `handover serve` with the simulated participant and both screens open for
# SOAK_MINUTES, participant after participant; prints the serve process's memory, open files and
# threads over time, and the run's end against its own baseline (benchmarks/serve_soak.py).
SOAK_MINUTES ?= 15
soak-serve: install chromium
	$(BIN)/python benchmarks/serve_soak.py --minutes $(SOAK_MINUTES)

bench: install
	$(BIN)/python benchmarks/control_loop.py

clean:
	rm -rf $(VENV) *.egg-info .mypy_cache
