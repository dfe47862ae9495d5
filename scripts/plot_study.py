#!/usr/bin/env python3
"""Plots of a rayfarm accuracy study (the study.csv `rayfarm study` writes).

Usage: plot_study.py STUDY_CSV OUT_DIR [--dpi N]

Writes, and prints the file names of, three PNGs in OUT_DIR:
  knobs.png   PSNR against render time, one panel per knob, its Pareto front drawn
  pareto.png  PSNR against time and against rays for every render, the front
              over all knobs drawn and the SPD setting (16 spp, depth 5) starred
  depth.png   error and time against the ray-tree depth
All numbers, the Pareto fronts included, come from the CSV; this script only
draws them. Knobs it has no style for get the next colour of the cycle.
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")  # no display on build machines
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
from matplotlib.ticker import NullFormatter  # noqa: E402

STYLE = {
    "spp": ("tab:blue", "o", "uniform spp"),
    "depth": ("tab:green", "^", "max depth"),
    "adaptive": ("tab:orange", "s", "adaptive spp/contrast"),
    "cutoff": ("tab:purple", "v", "ray-tree cutoff"),
    "robust": ("tab:red", "D", "robust BVH"),
}
SPARE = ["tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray"]
INTS = ("spp", "max_depth", "robust_bvh", "rays_total", "reused", "spd",
        "front", "front_rays", "front_all", "front_all_rays")
FLOATS = ("seconds", "rmse", "psnr_db", "max_abs", "knob_psnr_db", "knob_max_abs")


def number(text):
    """CSV cell to float: empty means 'not measured' (NaN), 'inf' is identical images."""
    return float(text) if text not in ("", None) else math.nan


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{path}: no rows")
    for row in rows:
        for key in FLOATS:
            row[key] = number(row[key])
        for key in INTS:
            row[key] = int(row[key])
    return rows


def sweeps(rows):
    """Knob names in CSV order, the reference left out."""
    names = []
    for r in rows:
        if r["sweep"] != "reference" and r["sweep"] not in names:
            names.append(r["sweep"])
    return names


def style(sweep, order):
    if sweep in STYLE:
        return STYLE[sweep]
    return (SPARE[order % len(SPARE)], "P", sweep)


def of(rows, sweep):
    return [r for r in rows if r["sweep"] == sweep]


def drawable(rows, cost):
    return [r for r in rows if math.isfinite(r["psnr_db"]) and r[cost] > 0]


def draw_front(ax, rows, cost, flag, **kw):
    front = sorted((r for r in drawable(rows, cost) if r[flag]), key=lambda r: r[cost])
    if front:
        ax.plot([r[cost] for r in front], [r["psnr_db"] for r in front], **kw)


def star_spd(ax, rows, cost):
    spd = [r for r in drawable(rows, cost) if r["spd"]][:1]
    if spd:
        ax.scatter([spd[0][cost]], [spd[0]["psnr_db"]], marker="*", s=220, color="gold",
                   edgecolors="black", zorder=5, label="SPD 16 spp, depth 5")


def plot_knobs(rows, scene, out, dpi):
    names = sweeps(rows)
    cols = min(3, len(names))
    nrows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(4.3 * cols, 3.5 * nrows), squeeze=False)
    for i, sweep in enumerate(names):
        ax = axes[i // cols][i % cols]
        color, marker, name = style(sweep, i)
        pts = drawable(of(rows, sweep), "seconds")
        if sweep == "adaptive":  # uniform sampling for comparison
            base = sorted(drawable(of(rows, "spp"), "seconds"), key=lambda r: r["seconds"])
            ax.plot([r["seconds"] for r in base], [r["psnr_db"] for r in base], "o-",
                    color="tab:blue", alpha=0.35, label="uniform spp")
        ax.scatter([r["seconds"] for r in pts], [r["psnr_db"] for r in pts], marker=marker,
                   color=color, label=name, zorder=3)
        draw_front(ax, pts, "seconds", "front", color=color, linestyle="--", alpha=0.8,
                   label="front")
        for r in pts:
            ax.annotate(r["value"], (r["seconds"], r["psnr_db"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
        star_spd(ax, pts, "seconds")
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())  # narrow ranges crowd minor labels
        ax.set_xlabel("render time (s)")
        ax.set_ylabel("PSNR vs reference (dB)")
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    for j in range(len(names), nrows * cols):
        axes[j // cols][j % cols].axis("off")
    fig.suptitle(f"{scene}: quality against time, one knob at a time from 16 spp, depth 5")
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)


def plot_pareto(rows, scene, out, dpi):
    """PSNR against time (as measured) and against rays traced (deterministic)."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    every = [r for r in rows if r["sweep"] != "reference"]
    for ax, cost, flag, xlabel in ((axes[0], "seconds", "front_all", "render time (s)"),
                                   (axes[1], "rays_total", "front_all_rays", "rays traced")):
        for i, sweep in enumerate(sweeps(rows)):
            color, marker, name = style(sweep, i)
            pts = drawable(of(rows, sweep), cost)
            ax.scatter([r[cost] for r in pts], [r["psnr_db"] for r in pts], color=color,
                       marker=marker, label=name, zorder=3, alpha=0.85)
        draw_front(ax, every, cost, flag, color="black", linestyle="--", alpha=0.6,
                   label="Pareto front", zorder=2)
        for r in drawable(every, cost):
            if r[flag] and not r["reused"]:
                ax.annotate(f"{r['sweep']} {r['value']}", (r[cost], r["psnr_db"]), fontsize=6,
                            xytext=(3, -9), textcoords="offset points")
        star_spd(ax, every, cost)
        ax.set_xscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("PSNR vs reference (dB)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{scene}: quality against cost, every render of the study")
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)


def plot_depth(rows, scene, out, dpi):
    pts = of(rows, "depth")
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    depths = [r["max_depth"] for r in pts]
    ax.plot(depths, [r["psnr_db"] for r in pts], "^-", color="tab:green", label="vs reference")
    alone = [r["knob_psnr_db"] if math.isfinite(r["knob_psnr_db"]) else math.nan for r in pts]
    ax.plot(depths, alone, "v:", color="tab:olive", label="vs deepest, same samples")
    ax.set_xlabel("max ray-tree depth (eye ray = 1)")
    ax.set_ylabel("PSNR (dB)", color="tab:green")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax2 = ax.twinx()
    ax2.plot(depths, [r["seconds"] for r in pts], "o--", color="tab:purple")
    ax2.set_ylabel("render time (s)", color="tab:purple")
    ax.set_title(f"{scene}: ray-tree depth (identical renders = inf dB, not drawn)")
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)


def main(argv):
    args = argv[1:]
    dpi = 100
    if "--dpi" in args:
        i = args.index("--dpi")
        dpi = int(args[i + 1])
        del args[i:i + 2]
    if len(args) != 2:
        sys.exit(__doc__)
    csv_path, out_dir = args
    rows = load(csv_path)
    scene = rows[0]["scene"]
    os.makedirs(out_dir, exist_ok=True)
    plots = [("knobs.png", plot_knobs), ("pareto.png", plot_pareto)]
    if of(rows, "depth"):
        plots.append(("depth.png", plot_depth))
    for name, draw in plots:
        draw(rows, scene, os.path.join(out_dir, name), dpi)
        print(name)


if __name__ == "__main__":
    main(sys.argv)
