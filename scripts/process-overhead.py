#!/usr/bin/env python3
"""What a `rayfarm render` process costs beyond its work, and its peak memory.

For each paper scene, interleaved rounds of three processes, each timed from
start to reap: /bin/true (what starting and reaping any process costs here),
`rayfarm render --help` (rayfarm's libraries loaded -- Embree, TBB,
libstdc++, libpng -- and its command line built, then exit: what every render
pays before its first line of work), and the render itself (one thread, a PNG
written, --stats). Per scene, medians over the rounds, in milliseconds:

  wall       the render's process
  phases     parse + build + render, as its --stats reports them
  overhead   wall - phases - /bin/true: the process's cost beyond its work
             and beyond any process's start (the 20 ms goal)
  start      of it, `render --help`'s wall - /bin/true: loading the
             libraries and the command line (the dynamic loader, the
             libraries' static constructors, their page faults)
  rest       overhead - start: what the render adds around its phases
             (the output file finished and synced, threads, exit)
  peak MiB   the render's maximum resident set (getrusage)

A benchmark, not a test: it prints numbers. Pin it (--cpus) on a noisy
machine, and read the ranges.

  scripts/process-overhead.py build/rayfarm --runs 11 --cpus 0,1
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = ["balls", "gears", "mount", "rings", "tetra"]


def timed(cmd):
    """Wall seconds from start to reap, and peak resident set in KiB; exits on failure."""
    # stderr to a file, not a pipe: a pipe nobody reads while the child runs
    # would stop a child that writes more than the pipe holds.
    with tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
        child.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait for it again
        if child.returncode != 0:
            err.seek(0)
            sys.exit(f"{' '.join(cmd)} failed ({child.returncode}): {err.read().decode().strip()}")
    return wall, usage.ru_maxrss


class Rounds:
    """One scene's per-round measurements, in milliseconds."""

    def __init__(self):
        self.wall, self.phases, self.overhead, self.start, self.rest, self.peak_mib = [], [], [], [], [], []

    def add(self, true_s, help_s, wall_s, phases_s, peak_kib):
        overhead, start = wall_s - phases_s - true_s, help_s - true_s
        self.wall.append(1e3 * wall_s)
        self.phases.append(1e3 * phases_s)
        self.overhead.append(1e3 * overhead)
        self.start.append(1e3 * start)
        self.rest.append(1e3 * (overhead - start))
        self.peak_mib.append(peak_kib / 1024)


def measure(a, scene, tmp):
    png, stats = os.path.join(tmp, "out.png"), os.path.join(tmp, "stats.json")
    render = [a.rayfarm, "render", os.path.join(HERE, "..", "scenes", scene + ".nff"), "-o", png,
              "--width", str(a.size), "--height", str(a.size), "--spp", "16", "--threads", "1", "--stats", stats]
    rounds = Rounds()
    for _ in range(a.runs):
        true_s, _ = timed(["/bin/true"])
        help_s, _ = timed([a.rayfarm, "render", "--help"])
        wall_s, peak_kib = timed(render)
        with open(stats) as f:
            seconds = json.load(f)["seconds"]
        rounds.add(true_s, help_s, wall_s, seconds["parse"] + seconds["build"] + seconds["render"], peak_kib)
    return rounds


def report(scene, r):
    def cell(values, width, digits=1):
        return f"{statistics.median(values):{width}.{digits}f}"
    spread = f"({min(r.overhead):.1f}-{max(r.overhead):.1f})"
    print(f"{scene:<6}{cell(r.wall, 9)}{cell(r.phases, 9)}{cell(r.overhead, 9)} {spread:<13}"
          f"{cell(r.start, 6)}{cell(r.rest, 6)}{cell(r.peak_mib, 9)}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("rayfarm", help="path of the rayfarm executable")
    ap.add_argument("--scenes", nargs="+", default=SCENES, choices=SCENES)
    ap.add_argument("--size", type=int, default=512, help="image width and height (default 512, the paper's)")
    ap.add_argument("--runs", type=int, default=9, help="interleaved rounds; medians are reported (default 9)")
    ap.add_argument("--cpus", help="processors to pin every process to, e.g. 0,1 (default: any)")
    a = ap.parse_args()
    if a.runs < 1 or a.size < 1:
        ap.error("--runs and --size must be at least 1")
    if not (os.path.isfile(a.rayfarm) and os.access(a.rayfarm, os.X_OK)):
        ap.error(f"{a.rayfarm} is not an executable (build first)")
    if a.cpus:
        try:
            os.sched_setaffinity(0, {int(c) for c in a.cpus.split(",")})
        except (ValueError, OSError) as e:
            ap.error(f"--cpus {a.cpus}: {e}")
    pinned = f"pinned to {a.cpus}" if a.cpus else "not pinned"
    print(f"{a.size}x{a.size}, 16 spp, 1 thread, PNG written; median of {a.runs} interleaved rounds, {pinned}; ms")
    print(f"{'scene':<6}{'wall':>9}{'phases':>9}{'overhead':>9} {'(range)':<13}{'start':>6}{'rest':>6}"
          f"{'peak MiB':>9}", flush=True)
    tmp = tempfile.mkdtemp(prefix="rayfarm-overhead-")
    try:
        for scene in a.scenes:
            report(scene, measure(a, scene, tmp))
    finally:
        shutil.rmtree(tmp)


if __name__ == "__main__":
    main()
