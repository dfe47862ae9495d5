#!/usr/bin/env bash
# Replay vs real throttled farms, one line per run: numbers, never pass/fail.
# Three 1-thread `rayfarm worker` processes throttled so that together they use
# about one core (throttle k renders, then sleeps (k-1) x the render time: ~1/k
# of a core), so the farm does not oversubscribe a 2-core machine and each
# worker runs at 1/throttle of the speed its row costs were measured at. Each
# run is replayed from the row costs measured before it (the prediction) and
# from the job record's own task times (the dispatch model alone).
# Usage: scripts/bench-validate.sh [RAYFARM] [OUT_DIR]   (default build/rayfarm, out/validate)
# Environment: VALIDATE_THROTTLES (2,3,4), VALIDATE_SPP (256), VALIDATE_SIZE (96x96),
#              VALIDATE_RUNS (2 per policy), VALIDATE_SCENE (scenes/balls.nff).
set -euo pipefail
RAYFARM=${1:-build/rayfarm}
OUT=${2:-out/validate}
THROTTLES=${VALIDATE_THROTTLES:-2,3,4}
SPP=${VALIDATE_SPP:-256}
SIZE=${VALIDATE_SIZE:-96x96}
RUNS=${VALIDATE_RUNS:-2}
SCENE=${VALIDATE_SCENE:-scenes/balls.nff}
mkdir -p "$OUT"
echo "# replay vs real throttled farms, $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# $SCENE, $SIZE, $SPP spp, throttles $THROTTLES (1 thread each), $RUNS run(s) per policy"
echo "# render = first dispatch -> last result; ratio = replay / real"
printf "%-9s %3s %9s %11s %6s %10s %6s %s\n" policy run "real s" "predicted s" ratio "replayed s" ratio "rows real | predicted"
for policy in paper weighted adaptive; do
  extra=()
  # weighted sizes tasks by declared weight: the workers declare their speed.
  [ "$policy" = weighted ] && extra=(--declare-speed --base-rows 2)
  for run in $(seq 1 "$RUNS"); do
    dir="$OUT/$policy-$run"
    "$RAYFARM" replay --validate --scene "$SCENE" --size "$SIZE" --spp "$SPP" --throttles "$THROTTLES" \
      --policy "$policy" --repeats 3 "${extra[@]}" -o "$dir" >/dev/null 2>"$dir.log" || { echo "$policy $run: failed, see $dir.log"; continue; }
    python3 - "$dir/validation.md" "$policy" "$run" <<'PYEOF'
import sys
md, policy, run = sys.argv[1:]
rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in open(md) if line.startswith("|")]
render = next(r for r in rows if r[0].startswith("render"))
workers = [r for r in rows if r[0].startswith("w") and "-x" in r[0]]
real = " / ".join(w[3].split()[0] for w in workers)
pred = " / ".join(w[4].split()[0] for w in workers)
print(f"{policy:<9} {run:>3} {render[1]:>9} {render[2]:>11} {render[3]:>6} {render[4]:>10} {render[5]:>6} {real} | {pred}")
PYEOF
  done
done | tee "$OUT/runs.txt"
# Each policy's median predicted / real: one run moves with the machine's
# speed, which here changes by up to 25% from one few-second phase to the next.
python3 - "$OUT/runs.txt" <<'PYEOF'
import statistics, sys
ratios = {}
for line in open(sys.argv[1]):
    f = line.split()
    if len(f) > 5 and f[0] in ("paper", "weighted", "adaptive") and f[4] != "ratio":
        ratios.setdefault(f[0], []).append(float(f[4]))
for policy, r in ratios.items():
    print(f"# {policy}: predicted / real median {statistics.median(r):.2f} over {len(r)} run(s), range {min(r):.2f}-{max(r):.2f}")
PYEOF
