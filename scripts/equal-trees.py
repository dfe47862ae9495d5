#!/usr/bin/env python3
"""rayfarm against Rayshade at equal ray trees: what each traced, and how long it took.

Rayshade's default stops a reflected ray whose weight falls below its cutoff
(0.002 in 4.0.6), and weighs a mirror bounce by `reflect` times the surface's
specular colour (the SPD library's highlight strength, which NFF lacks). On
rings (reflect 0.2, specular 0.3) a bounce weighs 0.06, so Rayshade's default
stops after two bounces, while rayfarm traces the full tree to --depth (5)
with NFF's weight (0.2), as Haines' ray counts assume. The two renderers'
default times thus price different work. This benchmark times each rayfarm
depth beside Rayshade with its cutoff off at the same depth (its -D counts the
bounces after the eye ray, rayfarm's --depth the eye ray too) and beside
Rayshade's default, with every run's rays by kind from the renderers' own
statistics, so that equal trees show as equal counts. 16 samples a pixel,
one thread, whole-process wall seconds: the median of interleaved rounds
and their range, for the machine's speed may wander between rounds. A
benchmark, not a test: it prints numbers.

  scripts/equal-trees.py build/rayfarm --rayshade PATH/rayshade \\
      --rayshade-inputs PATH/rayshade-inputs      # NAME-N.ray.gz per scene
"""
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from rayshade_peer import argument_parser, parse_arguments, unpack_input

HERE = os.path.dirname(os.path.abspath(__file__))
KINDS = ("eye", "shadow", "reflected", "refracted")


def run(cmd):
    """Runs cmd; returns (wall seconds, its stdout and stderr)."""
    start = time.perf_counter()
    try:
        done = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        sys.exit(f"cannot run {cmd[0]}: {e.strerror}")
    wall = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"failed ({done.returncode}): {' '.join(cmd)}\n{done.stderr[-2000:]}")
    return wall, done.stdout + done.stderr


class Renderer:
    """One configuration of one renderer: a command, and how to read its ray counts."""

    def __init__(self, label, cmd, counts, is_rayfarm, same_tree_as=None):
        self.label, self.cmd, self.read_counts = label, cmd, counts
        self.is_rayfarm = is_rayfarm
        self.same_tree_as = same_tree_as  # Rayshade: the rayfarm run that traces this run's tree
        self.walls, self.rays = [], None

    def time_once(self):
        wall, log = run(self.cmd)
        self.walls.append(wall)
        self.rays = self.read_counts(log)

    def median(self):  # of the wall seconds
        return statistics.median(self.walls)


def rayfarm_run(exe, scene, size, depth, tmp):
    stats = os.path.join(tmp, f"rf_{scene}_{depth}.json")
    cmd = [exe, "render", os.path.join(HERE, "..", "scenes", scene + ".nff"), "-o", os.path.join(tmp, "rf.png"),
           "--width", str(size), "--height", str(size), "--spp", "16", "--threads", "1", "--depth", str(depth),
           "--stats", stats]

    def counts(_log):
        with open(stats) as f:
            rays = json.load(f)["rays"]
        return {"eye": rays["eye"], "shadow": rays["shadow"], "reflected": rays["reflection"],
                "refracted": rays["refraction"]}
    return Renderer(f"rayfarm --depth {depth}", cmd, counts, is_rayfarm=True)


def rayshade_run(exe, ray, size, flags, label, tmp, same_tree_as=None):
    # -T -0.5: every pixel gets the full 4x4 jittered grid (16 samples), as in
    # rayfarm; the image is written to a file, as rayfarm's is.
    cmd = [exe, "-R", str(size), str(size), "-T", "-0.5", "-0.5", "-0.5"] + flags + \
        ["-O", os.path.join(tmp, "rs.mtv"), ray]

    def counts(log):
        found = {}
        for kind in KINDS:
            m = re.search(kind.capitalize() + r" rays:\s+(\d+)", log)
            if not m:
                sys.exit(f"no {kind} ray count in Rayshade's statistics ({' '.join(cmd)})")
            found[kind] = int(m.group(1))
        return found
    return Renderer(label, cmd, counts, is_rayfarm=False, same_tree_as=same_tree_as)


def scene_runs(a, scene, tmp):
    """Each rayfarm depth, each followed by Rayshade's same tree; then Rayshade's default."""
    runs = []
    ray = unpack_input(a.rayshade_inputs, scene, tmp) if a.rayshade else None
    for depth in a.depths:
        rayfarm = rayfarm_run(a.rayfarm, scene, a.size, depth, tmp)
        runs.append(rayfarm)
        if ray:
            runs.append(rayshade_run(a.rayshade, ray, a.size, ["-D", str(depth - 1), "-C", "0", "0", "0"],
                                     f"Rayshade -D {depth - 1} -C 0", tmp, rayfarm))
    if ray:
        runs.append(rayshade_run(a.rayshade, ray, a.size, [], "Rayshade default", tmp))
    return runs


def report(scene, runs):
    for r in runs:
        rays = "".join(f"{r.rays[k] / 1e6:10.3f}" for k in KINDS)
        spread = f"({min(r.walls):.2f}-{max(r.walls):.2f})"
        line = f"{scene:<6} {r.label:<22}{rays}{r.median():9.3f} {spread:<13}"
        if r.same_tree_as:
            line += f"   {r.median() / r.same_tree_as.median():.2f}x the time of {r.same_tree_as.label}"
        elif not r.is_rayfarm:  # Rayshade's default: beside every rayfarm depth
            line += "   " + ", ".join(f"{r.median() / f.median():.2f}x {f.label}" for f in runs if f.is_rayfarm)
        print(line.rstrip(), flush=True)


def main():
    ap = argument_parser(__doc__)
    ap.add_argument("--depths", type=int, nargs="+", default=[5, 3],
                    help="rayfarm --depth values, each beside Rayshade's tree of that depth (default 5 3)")
    ap.add_argument("--runs", type=int, default=3, help="interleaved rounds; the median is reported (default 3)")
    a = parse_arguments(ap)
    if a.runs < 1 or min(a.depths) < 1:
        ap.error("--runs and --depths must be at least 1")
    print(f"{a.size}x{a.size}, 16 spp, 1 thread; median of {a.runs} interleaved rounds; rays in millions")
    print(f"{'scene':<6} {'renderer':<22}" + "".join(f"{k:>10}" for k in KINDS) + "   wall s (range)", flush=True)
    tmp = tempfile.mkdtemp(prefix="rayfarm-equal-trees-")
    try:
        for scene in a.scenes:
            runs = scene_runs(a, scene, tmp)
            for _ in range(a.runs):
                for r in runs:
                    r.time_once()
            report(scene, runs)
    finally:
        shutil.rmtree(tmp)


if __name__ == "__main__":
    main()
