# Glimmer top-level Makefile. `make demo` and `make test` do all set-up on a
# fresh Debian 12 machine (dependencies via apt-get when missing).
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?=

SANITIZE_BUILD ?= build-sanitize
FUZZ_BUILD ?= build-fuzz
FUZZ_SECONDS ?= 600
FUZZ_RUNS ?= 1000000
FUZZ_TARGETS = fuzz_xml_loader fuzz_obj_reader fuzz_ply_reader fuzz_closure_params

.PHONY: all deps configure build demo test stress bench addon clean sanitize fuzz

all: build

deps:
	@bash tools/install_deps.sh

configure: deps
	@cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release $(CMAKE_FLAGS) > $(BUILD).configure.log 2>&1 || (cat $(BUILD).configure.log; exit 1)

build: configure
	@cmake --build $(BUILD) -j $(JOBS)

demo: build
	$(BUILD)/glimmer render examples/demo.xml -o demo.png --stats
	$(BUILD)/glimmer render examples/glint.xml -o demo_glint.png --stats
	$(BUILD)/glimmer render examples/frosted.xml -o demo_frosted.png --stats
	@test -s demo.png && test -s demo_glint.png && test -s demo_frosted.png && \
		echo "demo: wrote demo.png, demo_glint.png and demo_frosted.png"

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -LE stress

stress: build
	cd $(BUILD) && GLIMMER_STRESS=1 ctest --output-on-failure -j $(JOBS) -L stress

bench: build
	$(BUILD)/glimmer_benchmarks --benchmark_counters_tabular=true

# ASan + UBSan build in its own folder; runs the fast tests (no stress, no Blender).
sanitize: deps
	@cmake -S . -B $(SANITIZE_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGLIMMER_SANITIZE=ON > $(SANITIZE_BUILD).configure.log 2>&1 || (cat $(SANITIZE_BUILD).configure.log; exit 1)
	@cmake --build $(SANITIZE_BUILD) -j $(JOBS)
	cd $(SANITIZE_BUILD) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  ctest --output-on-failure -j $(JOBS) -LE "stress|addon"

# libFuzzer targets (clang, ASan + UBSan), each run for FUZZ_RUNS executions, at most FUZZ_SECONDS
# (tools/run_fuzz.sh prints executions, crashes, hangs > 5 s and sanitizer reports per target).
fuzz: deps
	@CC=clang CXX=clang++ cmake -S . -B $(FUZZ_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGLIMMER_FUZZ=ON -DBUILD_TESTING=OFF > $(FUZZ_BUILD).configure.log 2>&1 || (cat $(FUZZ_BUILD).configure.log; exit 1)
	@cmake --build $(FUZZ_BUILD) -j $(JOBS) --target $(FUZZ_TARGETS)
	bash tools/run_fuzz.sh $(FUZZ_BUILD) $(FUZZ_SECONDS) $(FUZZ_RUNS)

addon:
	@python3 tools/make_addon_zip.py

clean:
	rm -rf $(BUILD) $(BUILD).configure.log $(SANITIZE_BUILD) $(SANITIZE_BUILD).configure.log $(FUZZ_BUILD) $(FUZZ_BUILD).configure.log
