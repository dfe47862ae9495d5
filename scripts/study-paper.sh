#!/usr/bin/env bash
# The accuracy study on the paper's five SPD scenes (make study-paper): runs
# `rayfarm study` per scene at SIZE (default 512, the paper's size) with the
# converged references cached in out/reference (reruns skip them), then
# redraws each scene's plots small for the docs and copies its tables:
#   OUT/<scene>/       study.csv, study.md, full-size plots, images
#   docs/accuracy/<scene>/  study.md and small plots (committed)
#   docs/accuracy/summary.md  the SPD setting and the presets on every scene
# Besides every knob's sweep it measures PRESETS, candidate settings for previews
# and finals that change several knobs at once (docs/accuracy.md recommends from them).
# Override: SIZE=n SCENES="balls ..." OUT=dir REPEATS=n THREADS=n DOCS=0 (no docs) or
# DOCS=only (docs from an earlier run's OUT),
# PRESETS="spp=4,depth=4 ...", STUDY_ARGS="more rayfarm study options".
# Progress goes to stderr, one line per render, with the elapsed time.
set -euo pipefail

exe=${1:-build/rayfarm}
root="$(cd "$(dirname "$0")/.." && pwd)"
size=${SIZE:-512}
scenes=${SCENES:-"tetra balls mount rings gears"}
out=${OUT:-out/study-paper-$size}
repeats=${REPEATS:-2}
threads=${THREADS:-0}
docs=${DOCS:-1}
presets=${PRESETS:-"spp=4,depth=4 spp=4,depth=6,cutoff=0.03 spp=9,depth=6,adaptive=0.1 spp=16,depth=8,cutoff=0.01
  spp=36,depth=8,adaptive=0.05 spp=64,depth=10,cutoff=0.01"}
extra=${STUDY_ARGS:-}
for p in $presets; do extra="$extra --preset $p"; done

[ -x "$exe" ] || { echo "study-paper: $exe is not an executable (build first)" >&2; exit 1; }

start=$(date +%s)
n=$(echo $scenes | wc -w)
i=0
for s in $scenes; do
  [ "$docs" = only ] && break
  i=$((i + 1))
  echo "study-paper: scene $i/$n: $s at ${size}x${size}, $(( $(date +%s) - start )) s elapsed" >&2
  # shellcheck disable=SC2086  # STUDY_ARGS is a list of options
  "$exe" study "$root/scenes/$s.nff" -o "$out/$s" --size "$size" --repeats "$repeats" \
    --threads "$threads" --reference-cache "$root/out/reference" $extra >/dev/null
done
[ "$docs" = only ] || echo "study-paper: all $n scenes in $(( $(date +%s) - start )) s; tables and plots in $out/" >&2

[ "$docs" = 0 ] && exit 0
# The first Python with matplotlib, in the order `rayfarm study` tries them.
python=""
for candidate in ${RAYFARM_PYTHON:-} python3 /usr/bin/python3; do
  if "$candidate" -c 'import matplotlib' 2>/dev/null; then python=$candidate; break; fi
done
[ -n "$python" ] || { echo "study-paper: no python3 with matplotlib: docs not refreshed" >&2; exit 1; }
for s in $scenes; do
  mkdir -p "$root/docs/accuracy/$s"
  "$python" "$root/scripts/plot_study.py" "$out/$s/study.csv" "$root/docs/accuracy/$s" --dpi 64 >/dev/null
  # The per-scene tables, with the image links (which stay in out/) dropped.
  sed '/^## Images$/,/^## Plots$/{/^## Plots$/!d}' "$out/$s/study.md" >"$root/docs/accuracy/$s/study.md"
done
"$python" "$root/scripts/summarize_study.py" "$out" $scenes >"$root/docs/accuracy/summary.md"
echo "study-paper: docs/accuracy/<scene>/ and docs/accuracy/summary.md refreshed" >&2
