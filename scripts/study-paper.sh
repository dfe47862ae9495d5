#!/usr/bin/env bash
# The accuracy study on the paper's five SPD scenes (make study-paper): runs
# `rayfarm study` per scene at SIZE (default 512, the paper's size) with the
# converged references cached in out/reference (reruns skip them), then
# redraws each scene's plots small for the docs and copies its tables:
#   OUT/<scene>/       study.csv, study.md, full-size plots, images
#   docs/accuracy/<scene>/  study.md and small plots (committed)
#   docs/accuracy/summary.md  the SPD setting and the presets on every scene
# Override: SIZE=n SCENES="balls ..." OUT=dir REPEATS=n THREADS=n DOCS=0 (no docs).
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
extra=${STUDY_ARGS:-}

[ -x "$exe" ] || { echo "study-paper: $exe is not an executable (build first)" >&2; exit 1; }

start=$(date +%s)
n=$(echo $scenes | wc -w)
i=0
for s in $scenes; do
  i=$((i + 1))
  echo "study-paper: scene $i/$n: $s at ${size}x${size}, $(( $(date +%s) - start )) s elapsed" >&2
  # shellcheck disable=SC2086  # STUDY_ARGS is a list of options
  "$exe" study "$root/scenes/$s.nff" -o "$out/$s" --size "$size" --repeats "$repeats" \
    --threads "$threads" --reference-cache out/reference $extra >/dev/null
done
echo "study-paper: all $n scenes in $(( $(date +%s) - start )) s; tables and plots in $out/" >&2

[ "$docs" = 1 ] || exit 0
python=${RAYFARM_PYTHON:-python3}
for s in $scenes; do
  mkdir -p "$root/docs/accuracy/$s"
  "$python" "$root/scripts/plot_study.py" "$out/$s/study.csv" "$root/docs/accuracy/$s" --dpi 64 >/dev/null
  # The per-scene tables, with the image links (which stay in out/) dropped.
  sed '/^## Images$/,/^## Plots$/{/^## Plots$/!d}' "$out/$s/study.md" >"$root/docs/accuracy/$s/study.md"
done
"$python" "$root/scripts/summarize_study.py" "$out" $scenes >"$root/docs/accuracy/summary.md"
echo "study-paper: docs/accuracy/<scene>/ and docs/accuracy/summary.md refreshed" >&2
