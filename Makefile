# The two commands of the README: `make demo` (install + run the main job on the mock arm)
# and `make test` (install + run the whole test suite). Both create ./.venv on first use.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: install demo test chromium bench clean

install: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	@# A torch wheel that the machine provides locally (pip's find-links, e.g. a CPU build) is
	@# installed first; elsewhere this step finds nothing and the registry's torch is used.
	-$(BIN)/pip install --quiet --no-index --no-deps torch 2>/dev/null
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $@

demo: install
	$(BIN)/handover serve --study ./study

# The browser tests drive Debian's Chromium through Playwright (which cannot download its own
# browsers here); installed once with apt-get when missing.
chromium:
	@if [ ! -x /usr/bin/chromium ]; then \
		export DEBIAN_FRONTEND=noninteractive; \
		apt-get update -qq >/dev/null && apt-get install -y -qq chromium >/dev/null; \
	fi

test: install chromium
	$(BIN)/ruff check .
	$(BIN)/pytest

bench: install
	$(BIN)/python benchmarks/control_loop.py

clean:
	rm -rf $(VENV) *.egg-info
