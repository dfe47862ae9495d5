#!/usr/bin/env bash
# Tracer benchmark: renders the five SPD paper scenes at 512x512, 16 spp, on one
# thread (override: THREADS=n SPP=n SCENES="balls ..." SCENE_DIR=dir), and prints per scene
# the BVH build time, render time (wall), rays by kind and Mrays/s, plus the
# whole process's CPU time (parse + build + render + image write): when cpu_s is
# well below a render's wall time the core was shared. A benchmark, not a test:
# timings on a shared machine vary, so compare runs side by side.
set -euo pipefail

exe=${1:-build/rayfarm}
scene_dir=${SCENE_DIR:-"$(cd "$(dirname "$0")/.." && pwd)/scenes"}
threads=${THREADS:-1}
spp=${SPP:-16}
scenes=${SCENES:-"balls gears mount rings tetra"}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

[ -x "$exe" ] || { echo "bench-tracer: $exe is not an executable (build first)" >&2; exit 1; }

printf "rayfarm tracer benchmark: 512x512, %s spp, %s thread(s), %s\n" "$spp" "$threads" "$(date -u +%FT%TZ)"
printf "%-8s %9s %9s %7s %10s %10s %10s %10s %10s %8s\n" \
  scene build_ms render_s cpu_s eye eye_hit shadow reflect refract Mrays/s
for s in $scenes; do
  /usr/bin/time -f "%U %S" -o "$out/$s.time" "$exe" render "$scene_dir/$s.nff" -o "$out/$s.png" \
    --spp "$spp" --threads "$threads" --stats "$out/$s.json" >/dev/null
  python3 - "$s" "$out/$s.json" "$out/$s.time" <<'PY'
import json, sys
name, path, time_path = sys.argv[1], sys.argv[2], sys.argv[3]
cpu = sum(float(x) for x in open(time_path).read().split()[-2:])
j = json.load(open(path))
r, sec = j["rays"], j["seconds"]
total = r["eye"] + r["shadow"] + r["reflection"] + r["refraction"]
print("%-8s %9.1f %9.3f %7.2f %10d %10d %10d %10d %10d %8.2f" % (
    name.split("-")[0], 1e3 * sec["build"], sec["render"], cpu, r["eye"], r["eye_hit"], r["shadow"],
    r["reflection"], r["refraction"], total / sec["render"] / 1e6))
PY
done
