# Convenience front end to the CMake build in build/ (for people who just type make).
#   make          build the library (and demo, tests)
#   make demo     build and run eucsbademo on the bundled example problem
#   make test     build and run the whole test suite
#   make mex      build the MATLAB/GNU Octave interface into build/matlab (mex-test: its tests)
#   make install  install into PREFIX (default /usr/local)
BUILD ?= build
PREFIX ?= /usr/local
CMAKE_FLAGS ?=
JOBS ?= $(shell nproc 2>/dev/null || echo 2)

.PHONY: all configure test demo install clean deps-build deps-test mex mex-test deps-mex

# The main job: a generated 20-camera problem (data/README.md) through eucsbademo.
DEMO_PROBLEM ?= data/orbit-fixedK

all: deps-test configure
	cmake --build $(BUILD) -j $(JOBS)

deps-build:
	@sh scripts/deps.sh build

deps-test:
	@sh scripts/deps.sh test

configure:
	cmake -S . -B $(BUILD) -DCMAKE_INSTALL_PREFIX=$(PREFIX) -DSBA_BUILD_TESTS=ON $(CMAKE_FLAGS) >/dev/null

test: deps-test configure
	cmake --build $(BUILD) -j $(JOBS)
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

demo: deps-test configure
	cmake --build $(BUILD) -j $(JOBS) --target eucsbademo
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
