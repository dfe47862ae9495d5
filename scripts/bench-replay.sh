#!/usr/bin/env bash
# Replay benchmarks: numbers, never pass/fail.
#  1. Validation: real throttled farms on this machine (one 1-thread worker per
#     throttle) vs the replay of the same configuration, predicted from
#     measured row costs and replayed from the job record's own task times.
#  2. The paper's lab: the five SPD scenes, row costs measured here at 512x512
#     with reduced spp, scaled to the paper's sequential Sun SSC times (Table 2),
#     replayed on 1..46 SSCs and on all 80 machines; one speedup plot.
# Usage: scripts/bench-replay.sh [RAYFARM] [OUT_DIR]   (default build/rayfarm, out/replay)
set -euo pipefail
RAYFARM=${1:-build/rayfarm}
OUT=${2:-out/replay}
SPP=${REPLAY_SPP:-16}
SCENES=${REPLAY_SCENES:-"tetra balls mount rings gears"}
# Serialised start-up (scene over NFS on one 10 Mbps segment): the one free
# parameter, fitted so that Tetra on 46 SSCs takes the paper's 77.06 s.
STAGGER_MS=${REPLAY_STAGGER_MS:-600}
mkdir -p "$OUT"
echo "# rayfarm replay benchmark, $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, load: $(cut -d' ' -f1-3 /proc/loadavg)"

echo; echo "## Validation against real throttled farms"
run_validation() {  # name, then extra options
  local name=$1; shift
  echo; echo "### $name"; echo
  "$RAYFARM" replay --validate --scene scenes/balls.nff --repeats 3 -o "$OUT/validation-$name" "$@" 2>/dev/null
}
run_validation constant-1-2-3 --size 128x128 --spp 64 --throttles 1,2,3
run_validation constant-1-2-3-big --size 128x128 --spp 256 --throttles 1,2,3
run_validation weighted-base2-1-2-4 --size 128x128 --spp 64 --throttles 1,2,4 --policy weighted --declare-speed --base-rows 2
run_validation constant-1-1-4 --size 128x128 --spp 64 --throttles 1,1,4

echo; echo "## The paper's lab (costs measured at 512x512, $SPP spp, 1 thread; scaled to Table 2)"
echo "Main runs use credit 1 (the paper's policy: a server's next task is sent when it returns one);"
echo "the -credit2 runs use the worker configs' credit 2 (rayfarm's latency hiding), -weighted scales task size by SPECfp92."
LAB=configs/labs/paper-lab.json
csvs=()
staggered=()
for scene in $SCENES; do
  echo; echo "### $scene"; echo
  dir="$OUT/paper-$scene"
  "$RAYFARM" replay --scene "scenes/$scene.nff" --size 512x512 --spp "$SPP" --threads 1 --paper "$scene" \
    --lab "$LAB" --latency-ms 5 --stagger-ms 0 --policy paper --sweep --no-plots -o "$dir" 2>/dev/null | sed -n '/^## Whole lab/,$p'
  "$RAYFARM" replay --costs "$dir/costs.json" --lab "$LAB" --latency-ms 5 --policy weighted --sweep --no-plots \
    -o "$dir-credit2" >/dev/null 2>&1
  "$RAYFARM" replay --costs "$dir/costs.json" --lab "$LAB" --latency-ms 5 --credit 1 --policy weighted --sweep --no-plots \
    -o "$dir-weighted" >/dev/null 2>&1
  "$RAYFARM" replay --costs "$dir/costs.json" --lab "$LAB" --latency-ms 5 --policy paper --stagger-ms "$STAGGER_MS" \
    --sweep --no-plots -o "$dir-stagger" >/dev/null 2>&1
  csvs+=("$dir/sweep.csv")
  staggered+=("$dir-stagger/sweep.csv")
done
PY=python3
"$PY" -c 'import matplotlib' 2>/dev/null || PY=/usr/bin/python3
"$PY" scripts/plot_replay.py "${csvs[@]}" "$OUT" >/dev/null && echo && echo "plot: $OUT/speedup.png"
"$PY" scripts/plot_replay.py "${staggered[@]}" "$OUT/stagger" >/dev/null && echo "plot: $OUT/stagger/speedup.png"

echo; echo "## Predicted speedups vs the paper"; echo
"$PY" - "$OUT" $SCENES <<'PYEOF'
import csv, sys
out, scenes = sys.argv[1], sys.argv[2:]
paper = {"tetra": (22.91, None), "balls": (42.06, 64.19), "mount": (36.56, 52.72)}
def at(path, series, machines):
    for r in csv.DictReader(open(path)):
        if r["series"] == series and int(r["machines"]) == machines:
            return float(r["speedup"])
print("| scene | 46 SSC | 46 SSC, stagger | paper | 80 machines (85.2 norm.) | 80, stagger | paper | 46 SSC, credit 2 | 80, credit 2 | 80, weighted |")
print("|---|---|---|---|---|---|---|---|---|---|")
for s in scenes:
    d = f"{out}/paper-{s}"
    p46, p85 = paper.get(s, (None, None))
    cells = [at(f"{d}/sweep.csv", "homogeneous", 46), at(f"{d}-stagger/sweep.csv", "homogeneous", 46), p46,
             at(f"{d}/sweep.csv", "heterogeneous", 80), at(f"{d}-stagger/sweep.csv", "heterogeneous", 80), p85,
             at(f"{d}-credit2/sweep.csv", "homogeneous", 46), at(f"{d}-credit2/sweep.csv", "heterogeneous", 80),
             at(f"{d}-weighted/sweep.csv", "heterogeneous", 80)]
    print("| " + s + " | " + " | ".join("-" if c is None else f"{c:.2f}" for c in cells) + " |")
PYEOF
