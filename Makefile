# Two commands do all set-up on Debian 12 + Python 3.11 (as root):
#   make demo   # .venv + Debian packages + the project, then the end-to-end demo
#   make test   # the same set-up, then the whole test-suite under a virtual screen
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.appeal-installed
# jsPsych from the npm registry, pinned by its lock file; `appeal export web` copies it into a study
WEB_VENDOR := experiments/web/vendor
WEB_STAMP := $(WEB_VENDOR)/node_modules/.appeal-installed
# Every dependency pinned to the versions the test-suite last passed with (pip -c): a new
# release on PyPI cannot change a fresh install unannounced. `make upgrade-constraints` renews them.
CONSTRAINTS := constraints.txt
CYCLES_CONSTRAINTS := constraints-cycles.txt
# Blender's bpy (the Cycles path tracer) pins numpy < 2: it gets its own environment
CYCLES_VENV := .venv-cycles
CYCLES_STAMP := $(CYCLES_VENV)/.bpy-installed
XVFB := xvfb-run -a -s "-screen 0 1280x1024x24"
PYTEST_ARGS ?= -n 2
export PYOPENGL_PLATFORM ?= osmesa
export MPLBACKEND ?= Agg

.PHONY: demo test install cycles system-deps r-deps bench clean upgrade-constraints

demo: install
	$(XVFB) $(BIN)/appeal demo --out demo_out --force
	@echo "The demo report is at $(CURDIR)/demo_out/index.html"

test: install cycles
	$(XVFB) $(BIN)/python -m pytest $(PYTEST_ARGS)

install: system-deps $(STAMP) $(WEB_STAMP)

system-deps:
	@bash scripts/system-deps.sh

$(STAMP): pyproject.toml $(CONSTRAINTS)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -c $(CONSTRAINTS) -e '.[dev,fast,atlas]'
	$(BIN)/python -m pip install -q -c $(CONSTRAINTS) --no-deps 'pyrender==0.1.45'
	touch $(STAMP)

$(WEB_STAMP): $(WEB_VENDOR)/package.json $(WEB_VENDOR)/package-lock.json
	npm ci --prefix $(WEB_VENDOR) --no-audit --no-fund --loglevel=error
	touch $(WEB_STAMP)

# The optional path-traced tier (render: {engine: cycles}); `make test` installs it so its tests run.
cycles: $(CYCLES_STAMP)

$(CYCLES_STAMP): $(CYCLES_CONSTRAINTS)
	test -x $(CYCLES_VENV)/bin/python || $(PYTHON) -m venv $(CYCLES_VENV)
	$(CYCLES_VENV)/bin/python -m pip install -q --upgrade pip
	$(CYCLES_VENV)/bin/python -m pip install -q -c $(CYCLES_CONSTRAINTS) 'bpy==5.0.1'
	touch $(CYCLES_STAMP)

# Renew the pins: both environments built afresh with the newest releases the registry serves,
# frozen into constraints.txt and constraints-cycles.txt, then `make test` reinstalls from them and
# runs the whole suite. Green: commit the two files. Red: `git checkout constraints*.txt` and
# report what broke.
upgrade-constraints: system-deps
	rm -rf .venv-upgrade .venv-upgrade-cycles
	$(PYTHON) -m venv .venv-upgrade
	.venv-upgrade/bin/python -m pip install -q --upgrade pip
	.venv-upgrade/bin/python -m pip install -q -e '.[dev,fast,atlas]'
	.venv-upgrade/bin/python -m pip install -q --no-deps 'pyrender==0.1.45'
	bash scripts/freeze_constraints.sh .venv-upgrade $(CONSTRAINTS)
	$(PYTHON) -m venv .venv-upgrade-cycles
	.venv-upgrade-cycles/bin/python -m pip install -q --upgrade pip
	.venv-upgrade-cycles/bin/python -m pip install -q 'bpy==5.0.1'
	bash scripts/freeze_constraints.sh .venv-upgrade-cycles $(CYCLES_CONSTRAINTS) "the Cycles environment (.venv-cycles)"
	rm -rf .venv-upgrade .venv-upgrade-cycles
	$(MAKE) test

# R with car/afex/emmeans: only for benchmarks/anova.py and for re-deriving test references.
r-deps:
	@bash scripts/system-deps.sh r-base-core r-cran-car r-cran-afex r-cran-emmeans r-cran-lme4 r-cran-lmertest r-cran-pbkrtest r-cran-ordinal

bench: install
	for b in benchmarks/*.py; do $(XVFB) $(BIN)/python $$b || exit 1; done

clean:
	rm -rf demo_out .pytest_cache build *.egg-info .venv-upgrade .venv-upgrade-cycles
