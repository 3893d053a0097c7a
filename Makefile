# Glimmer top-level Makefile. `make demo` and `make test` do all set-up on a
# fresh Debian 12 machine (dependencies via apt-get when missing).
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?=

.PHONY: all deps configure build demo test stress bench addon clean

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

addon:
	@python3 tools/make_addon_zip.py

clean:
	rm -rf $(BUILD) $(BUILD).configure.log
