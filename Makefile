# furrow: two commands on a fresh Debian machine.
#   make demo   set up, then synthesise a scene, build its model, render it, write pictures + metrics
#   make test   set up, lint (ruff check .), then run the default test suite
# Both are idempotent: set-up steps are skipped when already done.

SHELL := /bin/bash
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Debian packages for headless OpenGL (Mesa llvmpipe through EGL) and Open3D (libusb).
DEB_PKGS := libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libgbm1 libusb-1.0-0
DEMO := out/demo
export OMP_WAIT_POLICY := passive

.PHONY: setup sysdeps lint test test-slow demo bench clean

sysdeps:
	@missing=$$(for p in $(DEB_PKGS); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q "install ok installed" || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = "0" ]; then \
	    echo "installing Debian packages: $$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	  else \
	    echo "error: missing Debian packages for headless OpenGL / Open3D: $$missing"; \
	    echo "run:   sudo apt-get install --no-install-recommends $$missing"; exit 1; \
	  fi; \
	fi

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev,cluster]'
	@touch $(STAMP)

setup: sysdeps $(STAMP)

# ruff: lint + import order, rules in pyproject.toml [tool.ruff]; `$(BIN)/ruff check --fix .` repairs most.
lint: setup
	$(BIN)/ruff check .

test: lint
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

test-slow: setup
	$(BIN)/python -m pytest -q -m slow

demo: setup
	bash scripts/demo.sh

bench: setup
	$(BIN)/furrow bench all

clean:
	rm -rf out .pytest_cache
