#!/usr/bin/env python3
"""Speedup plots of `rayfarm replay --sweep` (its sweep.csv), like the paper's
Fig. 3 (homogeneous: 1..46 Sun SSCs) and Fig. 4 (heterogeneous: all machines,
x = number of machines normalised to the SSC by SPECfp92).

Usage: plot_replay.py SWEEP_CSV [SWEEP_CSV ...] OUT_DIR

Several CSVs (one per scene) give one curve per scene. Writes speedup.png in
OUT_DIR and prints its name. Dashed: the perfect-speedup line; dotted: each
scene's init-time bound (sequential / init, paper section 4.3); crosses: the
speedups the paper reports.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")  # no display on build machines
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)

# Speedups stated in the paper's text: (series, normalised machines) -> {scene: speedup}.
PAPER = {
    ("homogeneous", 46.0): {"tetra": 22.91, "balls": 42.06, "mount": 36.56},
    ("heterogeneous", 85.0): {"balls": 64.19, "mount": 52.72},
}
SERIES = [("homogeneous", "Homogeneous (reference machines)"),
          ("heterogeneous", "Heterogeneous (all machines, lab order)")]


def load(paths):
    rows = []
    for path in paths:
        with open(path, newline="") as f:
            got = list(csv.DictReader(f))
        if not got:
            sys.exit(f"{path}: no rows")
        rows.extend(got)
    return rows


def curves(rows, series):
    """scene -> (x normalised, speedup, init_bound) for one series, in file order."""
    out = {}
    for r in rows:
        if r["series"] != series:
            continue
        xs, ys, bound = out.setdefault(r["scene"], ([], [], [float(r["init_bound"])]))
        xs.append(float(r["normalized"]))
        ys.append(float(r["speedup"]))
    return out


def panel(ax, rows, series, title):
    data = curves(rows, series)
    if not data:
        ax.set_visible(False)
        return
    xmax = max(max(xs) for xs, _, _ in data.values())
    ax.plot([0, xmax], [0, xmax], "k--", lw=1, label="perfect speedup")
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (scene, (xs, ys, bound)) in enumerate(sorted(data.items())):
        c = colors[i % len(colors)]
        ax.plot(xs, ys, "-", color=c, lw=1.5, label=scene)
        if 0 < bound[0] < 1.5 * xmax:
            ax.axhline(bound[0], color=c, ls=":", lw=1)
        for (s, x), ref in PAPER.items():
            if s == series and scene in ref:
                ax.plot([x], [ref[scene]], "x", color=c, ms=8, mew=2)
    ax.set_xlim(0, xmax * 1.02)
    ax.set_ylim(0, xmax * 1.02)
    ax.set_xlabel("machines (normalised to the reference machine)")
    ax.set_ylabel("speedup")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)


def main(argv):
    if len(argv) < 3:
        sys.exit(__doc__)
    out_dir = argv[-1]
    rows = load(argv[1:-1])
    os.makedirs(out_dir, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    for ax, (series, title) in zip(axes, SERIES):
        panel(ax, rows, series, title)
    fig.suptitle("rayfarm replay: predicted speedup (x = paper's reported value)")
    fig.tight_layout()
    name = "speedup.png"
    fig.savefig(os.path.join(out_dir, name), dpi=110)
    print(name)


if __name__ == "__main__":
    main(sys.argv)
