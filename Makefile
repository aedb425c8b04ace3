# The README's commands. Each bootstraps .venv itself.
#   make demo   set up, then run the main job (writes out/demo/)
#   make test   set up with the test extra, then run the test suite
#   make bench  set up, then run the benchmarks (bench/results.json)
# Developer loop: `make install` rebuilds incrementally (build/<wheel tag>).

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip --disable-pip-version-check
# Build requirements, installed into the venv so that editable installs can
# build without isolation (incremental, fixed build directory).
BUILD_REQS := "scikit-build-core>=0.10" "pybind11>=2.12" "cmeel-eigen>=3.4" "lcm>=1.5.1,<1.6" "cmake>=3.24" "ninja>=1.10"
PYTEST_ARGS ?=

.PHONY: all venv install demo test bench clean

all: install

$(PY):
	$(PYTHON) -m venv $(VENV)

$(VENV)/.build-reqs: $(PY)
	$(PIP) install -q $(BUILD_REQS)
	touch $@

venv: $(VENV)/.build-reqs

# Always re-run: scikit-build-core + ninja rebuild only what changed.
install: venv
	$(PIP) install -q --no-build-isolation -e '.[test]' -C build-dir=build/{wheel_tag}

demo: install
	$(VENV)/bin/sc-rt demo --out out/demo

test: install
	$(PY) -m pytest $(PYTEST_ARGS)

bench: install
	$(PY) bench/run_all.py

clean:
	rm -rf build out
