# rayfarm: the set-up commands (`make demo`, `make test`, `make sanitize`) and a few
# longer runs. Every target installs missing Debian packages first, then configures
# build/ (Release) or, for `make sanitize`, build-sanitize/ (ASan + UBSan).

MAKEFLAGS += --no-print-directory
BUILD   ?= build
JOBS    ?= $(shell nproc)
RAYFARM := $(BUILD)/rayfarm
DEMO_SCENE ?= balls
SANITIZE_BUILD ?= build-sanitize
FUZZ_SECONDS ?= 300
FUZZ_TARGETS := $(patsubst fuzz/%_fuzz.cpp,%,$(wildcard fuzz/*_fuzz.cpp))

.PHONY: all deps configure build test sanitize fuzz demo bench-tracer bench-replay bench-validate bench-service bench-broker bench-adaptive bench-equal-trees bench-overhead replay-paper study study-paper clean

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

# The whole suite again, built with AddressSanitizer and UndefinedBehaviorSanitizer
# (gcc, -O1 -g). Any report fails the test that caused it; see scripts/sanitize.sh.
sanitize: deps
	@./scripts/sanitize.sh $(SANITIZE_BUILD) $(JOBS)

# Each fuzz target (fuzz/README.md) for FUZZ_SECONDS; new inputs and crash
# artifacts go to $(BUILD)/fuzz/work/NAME/.
fuzz: build
	@for t in $(FUZZ_TARGETS); do \
	  echo "fuzz: $$t for $(FUZZ_SECONDS) s"; \
	  ./fuzz/run.sh $(BUILD)/fuzz $$t -max_total_time=$(FUZZ_SECONDS) -timeout=20 -rss_limit_mb=2048 \
	    -print_final_stats=1 || exit 1; \
	done

demo: build
	@mkdir -p out
	@$(RAYFARM) spd $(DEMO_SCENE) -o out/$(DEMO_SCENE).nff
	@$(RAYFARM) render out/$(DEMO_SCENE).nff -o out/$(DEMO_SCENE).png --workers 2 --stats out/$(DEMO_SCENE).stats.json
	@echo "demo image: $(CURDIR)/out/$(DEMO_SCENE).png"

bench-tracer: build
	@./scripts/bench-tracer.sh $(RAYFARM)

bench-replay: build
	@./scripts/bench-replay.sh $(RAYFARM)

# Replay vs real throttled 3-worker farms for the paper, weighted and adaptive
# policies: real render time, predicted, replayed from the job record.
bench-validate: build
	@./scripts/bench-validate.sh $(RAYFARM)

# The service: journal share of each job, the gap between jobs, rows
# rendered again after a kill -9 (scripts/bench-service.sh; SIZE=, SPP=, WORKERS=).
bench-service: build
	@./scripts/bench-service.sh $(RAYFARM)

# --adaptive's error against a 64-spp reference on the paper scenes; beside
# Rayshade's adaptive sampler when RAYSHADE= (an executable) and
# RAYSHADE_INPUTS= (a folder of NAME-N.ray.gz) are given; CUTOFF= prunes
# rayfarm's adaptive render (its reference stays the full tree).
bench-adaptive: build
	@./scripts/adaptive-error.py $(RAYFARM) $(if $(RAYSHADE),--rayshade $(RAYSHADE) --rayshade-inputs $(RAYSHADE_INPUTS)) $(if $(CUTOFF),--cutoff $(CUTOFF))

# rayfarm's ray trees and times beside Rayshade's at equal trees (its cutoff
# off) and at its default, rays counted by both (scripts/equal-trees.py);
# rayfarm alone unless RAYSHADE= and RAYSHADE_INPUTS= are given.
bench-equal-trees: build
	@./scripts/equal-trees.py $(RAYFARM) $(if $(RAYSHADE),--rayshade $(RAYSHADE) --rayshade-inputs $(RAYSHADE_INPUTS))

# A render process's cost beyond its parse, build and render, beside the
# floors of any process and of rayfarm's libraries, and its peak memory
# (scripts/process-overhead.py; RUNS=, CPUS= to pin, e.g. CPUS=0,1).
bench-overhead: build
	@./scripts/process-overhead.py $(RAYFARM) --runs $(or $(RUNS),9) $(if $(CPUS),--cpus $(CPUS))

bench-broker: configure
	@cmake --build $(BUILD) -j $(JOBS) --target rayfarm_bench_broker
	@$(BUILD)/rayfarm_bench_broker

replay-paper: build
	@./scripts/replay-paper.sh $(RAYFARM) out/replay-paper

study: build
	@$(RAYFARM) study scenes/balls.nff -o out/study-balls
	@$(RAYFARM) study scenes/mount.nff -o out/study-mount

# The five paper scenes at 512x512 (SIZE=256 for a quicker run); long: run it in
# the background. Writes out/study-paper-SIZE/ and refreshes docs/accuracy/.
study-paper: build
	@./scripts/study-paper.sh $(RAYFARM)

clean:
	rm -rf $(BUILD) $(SANITIZE_BUILD) out
