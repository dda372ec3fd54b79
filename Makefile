# Two-command set-up: `make run` and `make test` each create .venv and install
# everything on first use; later calls skip straight to the work (stamp file).
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip --disable-pip-version-check
STAMP := $(VENV)/.installed
export PYOPENGL_PLATFORM ?= egl
export MUJOCO_GL ?= egl
# Debian libraries for headless EGL rendering (pyrender, MuJoCo) and libusb for pyrealsense2.
APT_PACKAGES := libegl1 libgl1 libgbm1 libegl-mesa0 libgl1-mesa-dri libusb-1.0-0
# One test worker per core (pytest-xdist); each module stays on one worker so its fixtures
# are built once.
PYTEST_PARALLEL := -n auto --dist loadscope
PYTEST_DEFAULT := -m "not slow and not gpu and not hardware" $(PYTEST_PARALLEL)

.PHONY: setup run test test-all test-gpu bench lint format clean system-libs

setup: $(STAMP)

system-libs:
	@missing=""; for lib in libEGL.so.1 libGL.so.1 libgbm.so.1 libusb-1.0.so.0; do \
	  ldconfig -p | grep -q "$$lib" || missing="$$missing $$lib"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = "0" ]; then \
	    echo "installing Debian libraries for headless rendering (missing:$$missing)"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(APT_PACKAGES); \
	  else \
	    echo "error: missing system libraries:$$missing. Run: sudo apt-get install -y $(APT_PACKAGES)"; exit 1; \
	  fi; \
	fi

$(STAMP): setup.py pyproject.toml Makefile
	@$(MAKE) --no-print-directory system-libs
	@test -x $(PY) || $(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	# torch first, pinned to the local CPU wheel, so nothing later pulls a CUDA build
	$(PIP) install -q torch==2.13.0
	$(PIP) install -q -e ".[dev]"
	# pyrender pins PyOpenGL 3.1.0, which breaks MuJoCo's EGL backend; 3.1.10 works for both
	$(PIP) install -q PyOpenGL==3.1.10
	# digit-interface asks for opencv-python, which would clash with the contrib headless build
	$(PIP) install -q --no-deps digit-interface==0.2.1
	@touch $(STAMP)

run: $(STAMP)
	$(PY) run.py sensor=sim object=plushie

test: $(STAMP)
	$(PY) -m pytest $(PYTEST_DEFAULT) -q

test-all: $(STAMP)
	$(PY) -m pytest -m "not gpu and not hardware" $(PYTEST_PARALLEL) -q

test-gpu: $(STAMP)
	$(PY) -m pytest -m gpu -q

bench: $(STAMP)
	$(PY) -m neuralfeels_sem.bench --out bench.json

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: $(STAMP)
	$(VENV)/bin/ruff check --fix .
	$(VENV)/bin/ruff format .

clean:
	rm -rf outputs multirun bench.json .pytest_cache .ruff_cache build *.egg-info
	find . -name __pycache__ -type d -prune -not -path "./$(VENV)/*" -exec rm -rf {} +
