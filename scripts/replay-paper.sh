#!/usr/bin/env bash
# The paper's figures and numbers from the replay (make replay-paper), for the
# paper's policy (constant one-row tasks, one task at a time) and the default
# adaptive policy beside it. Row costs: scenes/costs/NAME.json (measured with
# the tracer at 512x512, 16 spp, 1 thread), scaled to Table 2 by --paper,
# which also starts the servers one after another as the paper's did
# (replay/paper_reference.h); lab-plain/ is the whole lab without that.
# Usage: scripts/replay-paper.sh [RAYFARM] [OUT_DIR]   (default build/rayfarm, out/replay-paper)
set -euo pipefail
RAYFARM=${1:-build/rayfarm}
OUT=${2:-out/replay-paper}
SCENES="tetra balls mount rings gears"
LAB=configs/labs/paper-lab.json
LAB38=configs/labs/paper-ssc-38.json
COMMON="--latency-ms 5 --no-plots"
mkdir -p "$OUT"
for scene in $SCENES; do
  costs=scenes/costs/$scene.json
  for policy in paper adaptive; do
    "$RAYFARM" replay --costs "$costs" --paper "$scene" --lab "$LAB" --policy "$policy" --sweep $COMMON \
      -o "$OUT/$policy/$scene/lab" >/dev/null 2>&1
    "$RAYFARM" replay --costs "$costs" --paper "$scene" --lab "$LAB" --policy "$policy" --stagger-ms 0 --sweep $COMMON \
      -o "$OUT/$policy/$scene/lab-plain" >/dev/null 2>&1
    "$RAYFARM" replay --costs "$costs" --paper "$scene" --lab "$LAB" --policy "$policy" --prior-frame $COMMON \
      -o "$OUT/$policy/$scene/lab-prior" >/dev/null 2>&1
    for k in $(seq 1 20); do  # Figure 1: 38 SSCs, k scanlines per task
      "$RAYFARM" replay --costs "$costs" --paper "$scene" --lab "$LAB38" --policy "$policy" --base-rows "$k" $COMMON \
        -o "$OUT/$policy/$scene/ssc38-k$k" >/dev/null 2>&1
      [ "$policy" = adaptive ] && break  # adaptive sizes its own tasks
    done
  done
  echo "replay-paper: $scene done" >&2
done
PY=python3
"$PY" -c 'import matplotlib' 2>/dev/null || PY=/usr/bin/python3
"$PY" scripts/plot_paper_figures.py "$OUT" $SCENES
