# Two commands do all set-up on Debian 12 + Python 3.11 (as root):
#   make demo   # .venv + Debian packages + the project, then the end-to-end demo
#   make test   # the same set-up, then the whole test-suite under a virtual screen
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.appeal-installed
# Blender's bpy (the Cycles path tracer) pins numpy < 2: it gets its own environment
CYCLES_VENV := .venv-cycles
CYCLES_STAMP := $(CYCLES_VENV)/.bpy-installed
XVFB := xvfb-run -a -s "-screen 0 1280x1024x24"
PYTEST_ARGS ?= -n 2
export PYOPENGL_PLATFORM ?= osmesa
export MPLBACKEND ?= Agg

.PHONY: demo test install cycles system-deps r-deps bench clean

demo: install
	$(XVFB) $(BIN)/appeal demo --out demo_out --force
	@echo "The demo report is at $(CURDIR)/demo_out/index.html"

test: install cycles
	$(XVFB) $(BIN)/python -m pytest $(PYTEST_ARGS)

install: system-deps $(STAMP)

system-deps:
	@bash scripts/system-deps.sh

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev,fast,atlas]'
	$(BIN)/python -m pip install -q --no-deps 'pyrender==0.1.45'
	touch $(STAMP)

# The optional path-traced tier (render: {engine: cycles}); `make test` installs it so its tests run.
cycles: $(CYCLES_STAMP)

$(CYCLES_STAMP):
	test -x $(CYCLES_VENV)/bin/python || $(PYTHON) -m venv $(CYCLES_VENV)
	$(CYCLES_VENV)/bin/python -m pip install -q --upgrade pip
	$(CYCLES_VENV)/bin/python -m pip install -q 'bpy==5.0.1'
	touch $(CYCLES_STAMP)

# R with car/afex/emmeans: only for benchmarks/anova.py and for re-deriving test references.
r-deps:
	@bash scripts/system-deps.sh r-base-core r-cran-car r-cran-afex r-cran-emmeans

bench: install
	for b in benchmarks/*.py; do $(XVFB) $(BIN)/python $$b || exit 1; done

clean:
	rm -rf demo_out .pytest_cache build *.egg-info
