#!/usr/bin/env bash
# Runs one fuzz target over its seed corpus (fuzz/corpus/NAME, only read) and a
# working corpus in the build folder, where libFuzzer keeps the new inputs it
# finds and writes crash/timeout/leak artifacts. Extra arguments go to libFuzzer.
# usage: fuzz/run.sh BUILD/fuzz NAME [-max_total_time=300 | -runs=N ...]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
bin=$1 name=$2
shift 2
work="$bin/work/$name"
mkdir -p "$work/corpus" "$work/artifacts"
dict=()
[ -f "$here/$name.dict" ] && dict=("-dict=$here/$name.dict")
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
exec "$bin/fuzz_$name" "${dict[@]}" -artifact_prefix="$work/artifacts/" "$@" "$work/corpus" "$here/corpus/$name"
