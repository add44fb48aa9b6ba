# The two commands a newcomer needs: `make demo` and `make test`. Both install missing Debian
# packages (scripts/deps.sh), build with CMake, then run.
BUILD ?= build
ASAN_BUILD ?= build-asan
JOBS ?= $(shell nproc 2>/dev/null || echo 2)

.PHONY: all deps deps-test build demo test test-sanitize fuzz bench format clean

all: build

deps:
	@bash scripts/deps.sh

# The test-only packages too (Blender for the blender_import test): `make demo` stays light.
deps-test: deps
	@bash scripts/deps.sh --test

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

demo: build
	@bash scripts/demo.sh $(BUILD)/kinemesh

test: deps-test build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -L unit

$(ASAN_BUILD)/CMakeCache.txt:
	cmake -S . -B $(ASAN_BUILD) -DCMAKE_BUILD_TYPE=Debug -DKM_SANITIZE=ON

# The same suite under AddressSanitizer + UndefinedBehaviorSanitizer (ctest label "sanitize").
test-sanitize: deps $(ASAN_BUILD)/CMakeCache.txt
	cmake --build $(ASAN_BUILD) -j $(JOBS)
	cd $(ASAN_BUILD) && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  ctest --output-on-failure -j $(JOBS) -L sanitize

# Every fuzz target (fuzz/fuzz_*.c) for FUZZ_SECONDS each (ctest `fuzz` runs them 5 s), or only
# FUZZ_TARGETS; findings and corpora in $(BUILD)/fuzz-long/<target>/.
FUZZ_SECONDS ?= 300
FUZZ_TARGETS ?=
fuzz: build
	KM_FUZZ_CLI=$(BUILD)/kinemesh bash fuzz/run.sh . $(BUILD)/fuzz-long $(FUZZ_SECONDS) $(FUZZ_TARGETS)

format:
	clang-format -i $$(git ls-files '*.c' '*.h')

clean:
	rm -rf $(BUILD) $(ASAN_BUILD) out
