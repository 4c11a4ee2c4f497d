# pkmbench — two commands on a fresh machine (python3, a C compiler, make):
#   make run    builds the venv (pinned deps) and the FMUs, then runs the default benchmark
#   make test   the same set-up, then the test suite
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: all venv fmus run test perf clean linuxcnc browser

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

# The suite on every core (pytest-xdist; TEST_WORKERS=0 runs it in one process), then the tests
# that run LinuxCNC's realtime process alone: its task/motion queue syncs follow the host's load.
# Both parts always run; the first failure's code is make's.
TEST_WORKERS ?= auto
test: fmus
	@rc=0; \
	$(BIN)/python -m pytest -n $(TEST_WORKERS) --dist worksteal -m "not realtime" || rc=$$?; \
	$(BIN)/python -m pytest -m realtime || { r=$$?; [ $$rc -ne 0 ] || rc=$$r; }; \
	exit $$rc

# LinuxCNC 2.9 (Debian's linuxcnc-uspace): the `linuxcnc` planner, the oracle tests and the
# G-code reference (rs274 and its gcode module; tests/test_rs274_reference.py); as root also
# the unprivileged user lcnc it runs under (rtapi_app refuses root). Without it those tests skip.
linuxcnc:
	@if command -v rs274 >/dev/null 2>&1 && command -v linuxcnc >/dev/null 2>&1; then \
	  echo "linuxcnc: LinuxCNC is installed ($$(command -v linuxcnc))"; \
	elif [ "$$(id -u)" -ne 0 ]; then \
	  echo "linuxcnc: not root: skipping the install (as root: make linuxcnc, or apt-get install linuxcnc-uspace)"; \
	elif ! command -v apt-get >/dev/null 2>&1; then \
	  echo "linuxcnc: no apt-get: install LinuxCNC 2.9 by hand to run its tests"; \
	else \
	  apt-get update -q && apt-get install -y --no-install-recommends linuxcnc-uspace; \
	fi
	@if [ "$$(id -u)" -eq 0 ] && ! id lcnc >/dev/null 2>&1; then \
	  useradd -m lcnc && echo "linuxcnc: created the user lcnc (LinuxCNC runs as it)"; fi

# Headless Chromium (Debian's): tests/test_html_report.py opens the HTML report in it and checks a
# screenshot; without it that test skips.
browser:
	@if command -v chromium >/dev/null 2>&1; then \
	  echo "browser: chromium is installed ($$(command -v chromium))"; \
	elif [ "$$(id -u)" -ne 0 ]; then \
	  echo "browser: not root: skipping the install (as root: make browser, or apt-get install chromium)"; \
	elif ! command -v apt-get >/dev/null 2>&1; then \
	  echo "browser: no apt-get: install chromium by hand to run the report's browser test"; \
	else \
	  apt-get update -q && apt-get install -y --no-install-recommends chromium; \
	fi

perf: fmus
	$(BIN)/python benchmarks/perf/run_all.py

clean:
	rm -rf fmus/build
