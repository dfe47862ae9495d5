#!/usr/bin/env bash
# Builds rayfarm with AddressSanitizer + UndefinedBehaviorSanitizer (-O1 -g,
# frame pointers kept for readable stacks) into a folder of its own and runs the
# whole ctest suite there: child processes the tests start (rayfarm render,
# broker, workers) are sanitized too. The first report aborts its process, so
# the test that caused it fails. Sanitized code runs ~2-5x slower, so each test
# gets a longer time limit rather than being skipped.
# usage: scripts/sanitize.sh [BUILD_DIR] [JOBS]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-sanitize}
jobs=${2:-$(nproc)}
sanitize="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"

cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS="$sanitize" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
  -DCMAKE_EXE_LINKER_FLAGS="$sanitize" -DCMAKE_MODULE_LINKER_FLAGS="$sanitize" \
  -DRAYFARM_FUZZ=OFF -DRAYFARM_TEST_TIMEOUT=900 >/dev/null
cmake --build "$build" -j "$jobs"

here=$(pwd)
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_string_checks=1:check_initialization_order=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$here/scripts/lsan.supp:print_suppressions=0}
cd "$build" && ctest --output-on-failure -j "$jobs"
