# SPDX-License-Identifier: BSD-3-Clause
# Convenience front end to the CMake build in build/ (for people who just type make).
# `make help` lists the targets.
BUILD ?= build
PREFIX ?= /usr/local
CMAKE_FLAGS ?=
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
# The interpreter pysba is built for: Debian's, whose pybind11 and numpy scripts/deps.sh installs.
PYTHON ?= $(shell test -x /usr/bin/python3 && echo /usr/bin/python3 || command -v python3)

.PHONY: all help configure test demo install clean deps-build deps-test mex mex-test deps-mex \
	check-kernels check-sanitize check-valgrind check-tsan check-fuzz soak check-bench configure-asan clean-checks

# The main job: a generated 20-camera problem (data/README.md) through eucsbademo.
DEMO_PROBLEM ?= data/orbit-fixedK
# The programs make demo builds: every one the README runs from build/demo.
DEMO_PROGRAMS = eucsbademo balsba sbarefine sbagen

all: deps-build configure
	cmake --build $(BUILD) -j $(JOBS)

help:
	@echo 'make              build the library, the programs (and the tests when GoogleTest is installed)'
	@echo 'make demo         install missing build packages, build the programs ($(DEMO_PROGRAMS)), run eucsbademo on $(DEMO_PROBLEM)'
	@echo 'make test         install missing build and test packages (pycolmap: a venv in BUILD), build, run the whole test suite (pysba too)'
	@echo 'make install      install into PREFIX (now $(PREFIX))'
	@echo 'make mex          the MATLAB/GNU Octave interface in $(BUILD)/matlab (make mex-test: its tests)'
	@echo 'make clean        remove $(BUILD)'
	@echo 'make check-kernels check-sanitize check-valgrind check-tsan check-fuzz soak check-bench: reliability checks'
	@echo 'Variables: BUILD=$(BUILD) PREFIX=$(PREFIX) JOBS=$(JOBS) CMAKE_FLAGS=...'

deps-build:
	@sh scripts/deps.sh build

# The venv of tests/pycolmap goes into the build directory, where the tests look for it.
deps-test:
	@SBA_PYCOLMAP_VENV=$(BUILD)/pycolmap-venv sh scripts/deps.sh test

# The test files at -O1: why, and the exception, in tests/CMakeLists.txt (SBA_TEST_OPTIMIZATION).
configure:
	cmake -S . -B $(BUILD) -DCMAKE_INSTALL_PREFIX=$(PREFIX) -DSBA_BUILD_TESTS=ON -DPython_EXECUTABLE=$(PYTHON) \
		-DSBA_TEST_OPTIMIZATION=-O1 $(CMAKE_FLAGS) >/dev/null

test: deps-test configure
	cmake --build $(BUILD) -j $(JOBS)
	ctest --test-dir $(BUILD) --output-on-failure --no-tests=error -j $(JOBS)

demo: deps-build configure
	cmake --build $(BUILD) -j $(JOBS) --target $(DEMO_PROGRAMS)
	$(BUILD)/demo/eucsbademo $(DEMO_PROBLEM)-cams.txt $(DEMO_PROBLEM)-pts.txt $(DEMO_PROBLEM)-calib.txt

deps-mex:
	@sh scripts/deps.sh mex

mex: deps-mex configure
	cmake -S . -B $(BUILD) -DSBA_BUILD_MEX=ON >/dev/null
	cmake --build $(BUILD) --target sba_mex -j $(JOBS)

mex-test: mex
	cmake --build $(BUILD) -j $(JOBS)
	ctest --test-dir $(BUILD) --output-on-failure -R '^octave_'

install: deps-build
	cmake -S . -B $(BUILD) -DCMAKE_INSTALL_PREFIX=$(PREFIX) -DSBA_BUILD_TESTS=OFF $(CMAKE_FLAGS) >/dev/null
	cmake --build $(BUILD) -j $(JOBS)
	cmake --install $(BUILD)

clean:
	rm -rf $(BUILD)

# ---- reliability checks (README, "Reliability") ----
#   make check-kernels    the numeric tests again under other OpenBLAS kernels and the library's
#                         portable ones (scripts/check_kernels.sh), in BUILD
#   make check-sanitize   the test suite under AddressSanitizer + UBSan + LeakSanitizer (build-asan/)
#   make check-valgrind   eucsbademo on DEMO_PROBLEM under valgrind memcheck
#   make check-tsan       the concurrency tests under ThreadSanitizer (build-tsan/)
#   make check-fuzz       every libFuzzer target of fuzz/ for FUZZ_SECONDS each, FUZZ_JOBS at once (build-fuzz/)
#   make soak             SOAK_N random solves with random faults (and SOAK_ASAN_N under ASan)
#   make check-bench      sba_bench (bench/, with Ceres) built in BUILD and its measurements checked
ASAN_BUILD ?= build-asan
TSAN_BUILD ?= build-tsan
FUZZ_BUILD ?= build-fuzz
# bench/run_suite.sh's tree (check-bench uses BUILD), removed by clean-checks
BENCH_BUILD ?= build-bench
FUZZ_SECONDS ?= 60
SOAK_N ?= 1000
SOAK_ASAN_N ?= $(SOAK_N)
SOAK_SEED ?= 1
# The sanitizer builds: optimized enough to be quick, with line numbers; no bench, no MEX file
# (octave-cli cannot load an instrumented one). The ASan build has the Python module: its
# tests preload ASan's runtime into python3 (python/CMakeLists.txt); ThreadSanitizer's cannot
# be preloaded that way, so the TSan build has none. -g1 keeps the line tables a report's stack
# needs and leaves out the variables' descriptions, which no report reads and which are slow to
# compile.
SAN_CMAKE_FLAGS = -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSBA_BUILD_TESTS=ON -DSBA_BUILD_MEX=OFF \
	-DSBA_BUILD_PYTHON=OFF -DSBA_BUILD_BENCH=OFF -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1" \
	-DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DSBA_TEST_OPTIMIZATION=-Og
ASAN_FLAGS = -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
TSAN_FLAGS = -fsanitize=thread -fno-omit-frame-pointer

check-kernels: deps-test configure
	cmake --build $(BUILD) -j $(JOBS)
	sh scripts/check_kernels.sh $(BUILD) $(JOBS)

configure-asan: deps-test
	cmake -S . -B $(ASAN_BUILD) $(SAN_CMAKE_FLAGS) -DSBA_BUILD_PYTHON=ON -DPython_EXECUTABLE=$(PYTHON) \
		-DCMAKE_C_FLAGS="$(ASAN_FLAGS)" \
		-DCMAKE_CXX_FLAGS="$(ASAN_FLAGS)" -DCMAKE_EXE_LINKER_FLAGS="$(ASAN_FLAGS)" \
		-DCMAKE_SHARED_LINKER_FLAGS="$(ASAN_FLAGS)" -DCMAKE_MODULE_LINKER_FLAGS="$(ASAN_FLAGS)" >/dev/null

check-sanitize: configure-asan
	cmake --build $(ASAN_BUILD) -j $(JOBS)
	sh scripts/check_sanitize.sh $(ASAN_BUILD) $(JOBS)

check-valgrind: deps-test configure
	@sh scripts/deps.sh valgrind
	cmake --build $(BUILD) -j $(JOBS) --target eucsbademo
	sh scripts/check_valgrind.sh $(BUILD)/demo/eucsbademo $(DEMO_PROBLEM)

check-tsan: deps-test
	cmake -S . -B $(TSAN_BUILD) $(SAN_CMAKE_FLAGS) -DCMAKE_C_FLAGS="$(TSAN_FLAGS)" \
		-DCMAKE_CXX_FLAGS="$(TSAN_FLAGS)" -DCMAKE_EXE_LINKER_FLAGS="$(TSAN_FLAGS)" \
		-DCMAKE_SHARED_LINKER_FLAGS="$(TSAN_FLAGS)" >/dev/null
	cmake --build $(TSAN_BUILD) -j $(JOBS) --target test_drivers test_solvers test_camera_params test_dense test_kernels test_parallel
	sh scripts/check_tsan.sh $(TSAN_BUILD)

check-fuzz: deps-build
	@sh scripts/deps.sh fuzz
	cmake -S fuzz -B $(FUZZ_BUILD) -DCMAKE_CXX_COMPILER=clang++-14 \
		-DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" >/dev/null
	cmake --build $(FUZZ_BUILD) -j $(JOBS)
	sh scripts/run_fuzz.sh $(FUZZ_BUILD) $(FUZZ_SECONDS)

# SOAK_N solves in the normal build (leaks counted by a counting operator new), then
# SOAK_ASAN_N more under AddressSanitizer (leaks found by LeakSanitizer in every child).
soak: configure configure-asan
	cmake --build $(BUILD) -j $(JOBS) --target sba_soak
	$(BUILD)/tests/sba_soak --solves $(SOAK_N) --seed $(SOAK_SEED)
	cmake --build $(ASAN_BUILD) -j $(JOBS) --target sba_soak
	ASAN_OPTIONS=detect_leaks=1 $(ASAN_BUILD)/tests/sba_soak --solves $(SOAK_ASAN_N) --seed $(SOAK_SEED)

# The instrument behind the README's performance figures, run on a small problem, its JSON
# checked (results and memory accounting, no timings). It is built in BUILD, whose library
# make test has already built (Release unless CMAKE_FLAGS says otherwise): the bench is turned
# on there explicitly, since a tree first configured before Ceres was installed keeps it off.
check-bench: deps-test configure
	@sh scripts/deps.sh bench
	cmake -S . -B $(BUILD) -DSBA_BUILD_BENCH=ON >/dev/null
	cmake --build $(BUILD) -j $(JOBS) --target sba_bench
	python3 bench/check_bench.py $(BUILD)/bench/sba_bench

clean-checks:
	rm -rf $(ASAN_BUILD) $(TSAN_BUILD) $(FUZZ_BUILD) $(BENCH_BUILD)
