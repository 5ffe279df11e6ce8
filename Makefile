# furrow: two commands on a fresh Debian machine.
#   make demo   set up, then synthesise a scene, build its model, render it, write pictures + metrics
#   make test   set up, lint (ruff check .), then run the default test suite
#   make hardcases  (optional) install Mitsuba 3 + Debian's libllvm19 and path-trace the hard cases
#               (scripts/hardcases.py) into HARDCASES_OUT; HARDCASES="name ..." picks cases
# Both are idempotent: set-up steps are skipped when already done.

SHELL := /bin/bash
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Debian packages for headless OpenGL (Mesa llvmpipe through EGL), Open3D (libusb) and the
# browser that the `furrow view` test drives (chromium; Playwright cannot download its own here).
DEB_PKGS := libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libgbm1 libusb-1.0-0 chromium
DEMO := out/demo
export OMP_WAIT_POLICY := passive

# The path-traced hard cases (optional; issue 30's table alone about 20 min on 2 AVX-512 cores, every case longer): Mitsuba 3's llvm_ad_rgb variant needs libLLVM,
# which Debian names libLLVM-19.so (DRJIT_LIBLLVM_PATH); the maps that are not bundled (city) come
# from Debian's blender-data (CC0 studio lights), unpacked under build/ without installing Blender.
HARDCASES_OUT ?= out/hardcases
HARDCASES ?=
BLENDER_MAPS := build/blender-data/usr/share/blender/datafiles/studiolights/world

.PHONY: setup sysdeps lint test test-slow demo bench clean pathtrace-deps hardcases

sysdeps:
	@missing=$$(for p in $(DEB_PKGS); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q "install ok installed" || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = "0" ]; then \
	    echo "installing Debian packages: $$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	  else \
	    echo "error: missing Debian packages for headless OpenGL / Open3D / the viewer test: $$missing"; \
	    echo "run:   sudo apt-get install --no-install-recommends $$missing"; exit 1; \
	  fi; \
	fi

# A new .venv holds about 3.5 GB of packages (Open3D alone 1.1 GB): without the room pip stops half way with
# "OSError: [Errno 28] No space left on device" (a CI run of stop 53), so say so first.
VENV_MB := 3600

$(STAMP): pyproject.toml
	@if [ ! -x $(BIN)/python ]; then \
	  free=$$(df -Pm . | awk 'NR==2 {print $$4}'); \
	  if [ "$$free" -lt $(VENV_MB) ]; then \
	    echo "error: the Python packages need about $(VENV_MB) MB in $(CURDIR)/$(VENV); that disk has $$free MB free"; \
	    exit 1; \
	  fi; \
	fi
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev,cluster]'
	@touch $(STAMP)

# numba compiles each kernel on its first call (80-100 s on a fresh clone here, pymatting's 50 s of it): done once
# here, on tiny captures in a temporary folder, so that neither the first `make demo` nor the tests pay it
# (scripts/warm_kernels.py); where that fails, set-up warns and goes on.
KERNELS := $(VENV)/.kernels-warm

$(KERNELS): $(STAMP)
	@if $(BIN)/python scripts/warm_kernels.py; then touch $(KERNELS); else \
	  echo "warning: compiling the numba kernels on a tiny capture failed (scripts/warm_kernels.py, its error above);"; \
	  echo "         furrow compiles each kernel on its first call instead, and set-up tries again next time"; fi

setup: sysdeps $(STAMP) $(KERNELS)

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

pathtrace-deps: setup
	@if ! ls /usr/lib/*/libLLVM-19.so >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = "0" ]; then \
	    echo "installing Debian package: libllvm19"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libllvm19; \
	  else \
	    echo "error: Mitsuba 3 (llvm_ad_rgb) needs Debian's libllvm19"; \
	    echo "run:   sudo apt-get install --no-install-recommends libllvm19"; exit 1; \
	  fi; \
	fi
	$(BIN)/python -c "import mitsuba" 2>/dev/null || $(BIN)/python -m pip install -q -e '.[pathtrace]'

$(BLENDER_MAPS)/city.exr:
	mkdir -p build/blender-data
	cd build/blender-data && rm -f blender-data_*.deb && \
	  { apt-get download blender-data || { apt-get update -qq && apt-get download blender-data; }; } && \
	  dpkg -x blender-data_*.deb .

hardcases: pathtrace-deps $(BLENDER_MAPS)/city.exr
	DRJIT_LIBLLVM_PATH=$$(ls /usr/lib/*/libLLVM-19.so | head -1) nice -n 10 \
	  $(BIN)/python scripts/hardcases.py -o $(HARDCASES_OUT) --env-dir $(BLENDER_MAPS) $(HARDCASES)

clean:
	rm -rf out .pytest_cache
