# rayfarm: the two set-up commands (`make demo`, `make test`) and a few longer runs.
# Every target installs missing Debian packages first, then configures build/ (Release).

MAKEFLAGS += --no-print-directory
BUILD   ?= build
JOBS    ?= $(shell nproc)
RAYFARM := $(BUILD)/rayfarm
DEMO_SCENE ?= balls

.PHONY: all deps configure build test demo bench-tracer bench-replay study study-paper clean

all: build

deps:
	@./scripts/install-deps.sh

$(BUILD)/CMakeCache.txt: | deps
	@cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release >/dev/null

configure: deps $(BUILD)/CMakeCache.txt

build: configure
	@cmake --build $(BUILD) -j $(JOBS)

test: build
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

demo: build
	@mkdir -p out
	@$(RAYFARM) spd $(DEMO_SCENE) -o out/$(DEMO_SCENE).nff
	@$(RAYFARM) render out/$(DEMO_SCENE).nff -o out/$(DEMO_SCENE).png --workers 2 --stats out/$(DEMO_SCENE).stats.json
	@echo "demo image: $(CURDIR)/out/$(DEMO_SCENE).png"

bench-tracer: build
	@./scripts/bench-tracer.sh $(RAYFARM)

bench-replay: build
	@./scripts/bench-replay.sh $(RAYFARM)

study: build
	@$(RAYFARM) study scenes/balls.nff -o out/study-balls
	@$(RAYFARM) study scenes/mount.nff -o out/study-mount

# The five paper scenes at 512x512 (SIZE=256 for a quicker run); long: run it in
# the background. Writes out/study-paper-SIZE/ and refreshes docs/accuracy/.
study-paper: build
	@./scripts/study-paper.sh $(RAYFARM)

clean:
	rm -rf $(BUILD) out
