# nbvkit: the README's two commands live here.
#   make        set up everything on a fresh Debian 12 machine (as root) and run the main job
#   make test   run the whole test suite (C++ GoogleTest + pytest)
SHELL := /bin/bash
PY_SYS := /usr/bin/python3
VENV := .venv
PY := $(VENV)/bin/python
PIP_FLAGS := --no-build-isolation --no-index
export MPLBACKEND := Agg

APT_PACKAGES := build-essential cmake ninja-build pybind11-dev libeigen3-dev liboctomap-dev \
  libpcl-dev libembree-dev libassimp-dev libtbb-dev libgtest-dev libbenchmark-dev \
  python3-dev python3-venv python3-pip python3-setuptools python3-wheel python3-numpy \
  python3-pytest python3-open3d python3-matplotlib python3-tqdm python3-yaml python3-scipy \
  python3-nbformat python3-nbclient python3-ipykernel python3-nbconvert \
  python3-dask python3-distributed python3-pandas xvfb python3-plotly chromium \
  clang-format black python3-flake8 python3-pymap3d python3-fastkml python3-lxml \
  python3-pyproj proj-data

.PHONY: all deps venv install demo test test-cpp test-asan test-py lint format bench clean

all: install demo

# System packages (skipped when all are present already; needs root otherwise).
deps:
	@missing=$$(for p in $(APT_PACKAGES); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q "ok installed" || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing system packages:" $$missing; \
	  SUDO=$$( [ $$(id -u) -eq 0 ] || echo sudo ); \
	  $$SUDO apt-get update -q && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -q $$missing; \
	else echo "system packages: all present"; fi

$(VENV)/bin/python:
	$(PY_SYS) -m venv --system-site-packages $(VENV)

venv: deps $(VENV)/bin/python

# Builds the extension with CMake (incremental: build/cmake-*) and installs nbvkit editable.
install: venv
	$(PY) -m pip install $(PIP_FLAGS) -q -e .
	@$(PY) -m ipykernel install --sys-prefix --name python3 >/dev/null  # notebooks run in the venv
	@$(PY) -c "import nbvkit, sys; print('nbvkit', nbvkit.__version__, 'installed in', sys.prefix)"

demo:
	$(VENV)/bin/nbvkit run --out runs/main --overwrite  # make again: the run again, in its place

test: install test-cpp test-py

# The GoogleTest binary is built in the extension's own build tree, sharing its objects.
BUILD_DIR = build/cmake-$(shell $(PY) -c "import sysconfig; print(sysconfig.get_config_var('SOABI') or 'py')" 2>/dev/null)

test-cpp: install
	cmake -S . -B $(BUILD_DIR) -DNBV_BUILD_TESTS=ON >/dev/null
	cmake --build $(BUILD_DIR) --target nbv_tests -j 2
	cd $(BUILD_DIR) && ctest --output-on-failure

# The GoogleTests under AddressSanitizer + UndefinedBehaviorSanitizer, in their own build tree
# (no Python extension; any report fails the run). Under ASan, Eigen stops trusting glibc's
# 16-byte malloc alignment and switches to its own allocator, which Debian's prebuilt PCL (built
# without ASan) does not share: frees inside libpcl then report bad-free. The define keeps
# Eigen's allocation as in the libraries.
ASAN_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=undefined \
  -fno-omit-frame-pointer -DEIGEN_MALLOC_ALREADY_ALIGNED=1
test-asan:
	cmake -S . -B build/asan -G Ninja -DNBV_BUILD_PYTHON=OFF -DNBV_BUILD_TESTS=ON \
	  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS="$(ASAN_FLAGS)" \
	  -DCMAKE_EXE_LINKER_FLAGS="$(ASAN_FLAGS)" >/dev/null
	cmake --build build/asan --target nbv_tests -j 2
	cd build/asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure

test-py:
	$(PY) -m pytest -q tests

# Style: clang-format (.clang-format), black + flake8 (pyproject.toml, .flake8); 100 columns.
CXX_FILES = $(shell git ls-files 'cpp/*.cpp' 'cpp/*.hpp' 'bench/*.cpp')
PY_DIRS = python tests bench meshes setup.py

lint:
	clang-format --dry-run --Werror $(CXX_FILES)
	@awk 'length > 100 { print FILENAME ":" FNR ": line longer than 100 columns"; bad = 1 } END { exit bad }' $(CXX_FILES)
	black --check -q $(PY_DIRS)
	$(PY_SYS) -m flake8 $(PY_DIRS)

format:
	clang-format -i $(CXX_FILES)
	black -q $(PY_DIRS)

# Every benchmark prints its figures and its baseline ratio (docs/RESULTS.md, "Measured figures").
bench: install
	for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf build $(VENV) python/nbvkit/_core*.so
