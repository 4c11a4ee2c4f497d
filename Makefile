# pkmbench — two commands on a fresh machine (python3, a C compiler, make):
#   make run    builds the venv (pinned deps) and the FMUs, then runs the default benchmark
#   make test   the same set-up, then the test suite
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: all venv fmus run test perf clean linuxcnc

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

# LinuxCNC's interpreter (rs274 and its gcode Python module): the reference of the G-code tests
# (tests/test_rs274_reference.py skips without it). Installs linuxcnc-uspace as root with apt.
linuxcnc:
	@if command -v rs274 >/dev/null 2>&1; then echo "linuxcnc: rs274 is installed"; \
	elif [ "$$(id -u)" != 0 ]; then echo "linuxcnc: skipped (not root): apt-get install linuxcnc-uspace to run the rs274 reference tests"; \
	elif ! command -v apt-get >/dev/null 2>&1; then echo "linuxcnc: skipped (no apt-get): install LinuxCNC 2.9 to run the rs274 reference tests"; \
	else apt-get update && apt-get install -y --no-install-recommends linuxcnc-uspace; fi
