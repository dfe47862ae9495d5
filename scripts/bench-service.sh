#!/usr/bin/env bash
# Service benchmark: a `rayfarm broker --serve` with WORKERS local workers
# (threads 1 each) renders the five SPD scenes as five queued jobs at SIZE
# pixels wide, SPP samples, then a throttled job that is killed (-9) half way
# and resumed. Prints, from the job records and statuses:
#   journal_%  seconds spent journaling rows / the frame's wall time
#   gap_ms     previous job's last row -> this job's first hand-out
#   next_init  the workers' parse + BVH build of this job (what the gap would
#              be if the job were announced only when the last one ended)
#   kill       rows journaled at the kill, rows resumed after the restart, rows
#              rendered again (those handed out and not returned at the kill)
# A benchmark, not a test: timings on a shared machine vary.
set -euo pipefail

exe=${1:-build/rayfarm}
root="$(cd "$(dirname "$0")/.." && pwd)"
workers=${WORKERS:-2}
size=${SIZE:-256}
spp=${SPP:-4}
state=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done; rm -rf "$state"; }
trap cleanup EXIT

[ -x "$exe" ] || { echo "bench-service: $exe is not an executable (build first)" >&2; exit 1; }

start_broker() {  # [http port] [worker port]
  rm -f "$state/st/service.json"
  "$exe" broker --serve --state "$state/st" --http "127.0.0.1:${1:-0}" --bind "tcp://127.0.0.1:${2:-*}" \
    --announce 'tcp://127.0.0.1:*' --no-progress --heartbeat-ms 200 >>"$state/broker.log" 2>&1 &
  broker=$!
  disown "$broker"  # killed on purpose: no job-control notice
  pids+=("$broker")
  for _ in $(seq 100); do [ -s "$state/st/service.json" ] && break; sleep 0.1; done
  http=$(python3 -c "import json,sys;print(json.load(open(sys.argv[1]))['http'])" "$state/st/service.json")
  endpoint=$(python3 -c "import json,sys;print(json.load(open(sys.argv[1]))['workers'])" "$state/st/service.json")
}
start_workers() {  # throttle
  for i in $(seq "$workers"); do
    "$exe" worker --connect "$endpoint" --threads 1 --throttle "$1" --heartbeat-ms 200 --quiet --name "w$i" \
      >>"$state/workers.log" 2>&1 &
    pids+=("$!")
    disown "$!"
  done
}

start_broker
start_workers 1
printf "rayfarm service benchmark: %s workers x 1 thread, %spx wide, %s spp, %s\n" "$workers" "$size" "$spp" \
  "$(date -u +%FT%TZ)"
jobs=()
for s in balls gears mount rings tetra; do
  jobs+=("$("$exe" submit "$root/scenes/$s.nff" --width "$size" --spp "$spp" --broker "$http" 2>/dev/null)")
done
"$exe" fetch "${jobs[-1]}" -o "$state/last.png" --wait --broker "$http" 2>/dev/null
python3 - "$state/st/jobs" "${jobs[@]}" <<'PY'
import json, statistics, sys
root, ids = sys.argv[1], sys.argv[2:]
print(f"{'job':>4} {'scene':<8} {'total_s':>8} {'journal_ms':>10} {'journal_%':>9} {'gap_ms':>8} {'next_init_ms':>12}")
shares, gaps, inits = [], [], []
for i in ids:
    r = json.load(open(f"{root}/{i}/record-0001.json"))
    share = 100 * r["journal_s"] / r["total_s"]
    init = max(w["init_s"] for w in r["workers"])
    gap = r["gap_s"]
    shares.append(share)
    if gap is not None:
        gaps.append(gap); inits.append(init)
    print(f"{i:>4} {r['scene'].split('/')[-1][:-4]:<8} {r['total_s']:8.3f} {1000*r['journal_s']:10.2f} {share:9.3f} "
          f"{'-' if gap is None else f'{1000*gap:8.1f}':>8} {1000*init:12.1f}")
print(f"median journal share {statistics.median(shares):.3f} %; median gap {1000*statistics.median(gaps):.1f} ms "
      f"vs median next-job init {1000*statistics.median(inits):.1f} ms")
PY

# Kill -9 half way through a throttled job, restart on the same ports, finish.
for p in "${pids[@]:1}"; do kill "$p" 2>/dev/null || true; done
start_workers 60
job=$("$exe" submit "$root/scenes/balls.nff" --width 128 --spp "$spp" --broker "$http" 2>/dev/null)
while :; do
  done_rows=$("$exe" status "$job" --json --broker "$http" 2>/dev/null | python3 -c "import json,sys;print(json.load(sys.stdin)['rows_done'])")
  [ "$done_rows" -ge 64 ] && break
  sleep 0.05
done
kill -9 "$broker"
while kill -0 "$broker" 2>/dev/null; do sleep 0.05; done
start_broker "${http##*:}" "${endpoint##*:}"
"$exe" fetch "$job" -o "$state/killed.png" --wait --broker "$http" 2>/dev/null
"$exe" render "$root/scenes/balls.nff" --width 128 --spp "$spp" -o "$state/ref.png" >/dev/null
same=$(cmp -s "$state/killed.png" "$state/ref.png" && echo identical || echo DIFFERENT)
"$exe" status "$job" --json --broker "$http" 2>/dev/null | python3 -c "
import json, sys
s = json.load(sys.stdin)
print(f'kill -9 with {sys.argv[1]} of 128 rows journaled: resumed {s[\"resumed_rows\"]}, '
      f'rendered again {s[\"rerendered_rows\"]} (handed out, not returned at the kill); image {sys.argv[2]}')" \
  "$done_rows" "$same"
