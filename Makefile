# pkmbench — two commands on a fresh machine (python3, a C compiler, make):
#   make run    builds the venv (pinned deps) and the FMUs, then runs the default benchmark
#   make test   the same set-up, then the test suite
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: all venv fmus run test perf clean

all: fmus

# Reinstall only when the dependency declaration or the lock changes.
$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --disable-pip-version-check -c constraints.txt -e ".[dev]"
	touch $@

venv: $(STAMP)

fmus: $(STAMP)
	@if [ -f fmus/build.py ]; then $(BIN)/python fmus/build.py; fi

run: fmus
	$(BIN)/pkmbench run benchmarks/suites/default.toml

test: fmus
	$(BIN)/python -m pytest

perf: fmus
	$(BIN)/python benchmarks/perf/run_all.py

clean:
	rm -rf fmus/build
