#!/usr/bin/env python3
"""Plots of a rayfarm accuracy study (the study.csv `rayfarm study` writes).

Usage: plot_study.py STUDY_CSV OUT_DIR

Writes, and prints the file names of, three PNGs in OUT_DIR:
  error_vs_time.png  RMSE against render time, one panel per knob
  pareto.png         PSNR against time for every render, Pareto front marked
  depth.png          truncation error and time against the ray-tree depth
All numbers come from the CSV; this script only draws them.
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")  # no display on build machines
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)

SWEEP_STYLE = {
    "spp": ("tab:blue", "o", "uniform spp"),
    "adaptive": ("tab:orange", "s", "adaptive"),
    "depth": ("tab:green", "^", "max depth"),
    "cutoff": ("tab:purple", "v", "cutoff"),
    "robust": ("tab:red", "D", "robust on/off"),
}


def number(text):
    """CSV cell to float: empty means 'not measured' (NaN), 'inf' is identical images."""
    return float(text) if text not in ("", None) else math.nan


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{path}: no rows")
    for row in rows:
        for key in ("seconds", "rmse", "psnr_db", "adaptive_contrast", "cutoff", "rays_total"):
            row[key] = number(row[key])
        for key in ("spp", "max_depth", "robust_bvh"):
            row[key] = int(row[key])
    return rows


def of(rows, sweep):
    return [r for r in rows if r["sweep"] == sweep]


def label(row):
    if row["sweep"] == "spp":
        return f"{row['spp']}"
    if row["sweep"] == "adaptive":
        return f"{row['spp']}/{row['adaptive_contrast']:g}"
    if row["sweep"] == "depth":
        return f"d{row['max_depth']}"
    if row["sweep"] == "cutoff":
        return f"c{row['cutoff']:g}"
    if row["sweep"] == "robust":
        return "on" if row["robust_bvh"] else "off"
    return ""


def finite(rows, key):
    return [r for r in rows if math.isfinite(r[key]) and r[key] > 0 and r["seconds"] > 0]


def plot_error_vs_time(rows, scene, out):
    sweeps = [s for s in ("spp", "adaptive", "cutoff", "depth", "robust") if of(rows, s)]
    fig, axes = plt.subplots(1, len(sweeps), figsize=(4.2 * len(sweeps), 3.8), squeeze=False)
    for ax, sweep in zip(axes[0], sweeps):
        color, marker, name = SWEEP_STYLE[sweep]
        pts = finite(of(rows, sweep), "rmse")
        if sweep == "adaptive":  # uniform sampling for comparison
            base = finite(of(rows, "spp"), "rmse")
            ax.plot([r["seconds"] for r in base], [r["rmse"] for r in base], "o-",
                    color="tab:blue", alpha=0.5, label="uniform spp")
        ax.plot([r["seconds"] for r in pts], [r["rmse"] for r in pts], marker,
                linestyle="-" if sweep != "adaptive" else "", color=color, label=name)
        for r in pts:
            ax.annotate(label(r), (r["seconds"], r["rmse"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("render time (s)")
        ax.set_ylabel("RMSE vs " + (pts[0]["baseline"] if pts else "reference"))
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"{scene}: error against time per knob")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def pareto_front(points):
    """Points (time, psnr) not beaten by another that is both faster and better."""
    front, best = [], -math.inf
    for t, q in sorted(points):
        if q > best:
            front.append((t, q))
            best = q
    return front


def plot_pareto(rows, scene, out):
    """PSNR against time (as measured) and against rays traced (deterministic)."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    for ax, cost, xlabel in ((axes[0], "seconds", "render time (s)"),
                             (axes[1], "rays_total", "rays traced")):
        everything = []
        for sweep in ("spp", "adaptive", "cutoff", "robust"):
            pts = [r for r in of(rows, sweep) if math.isfinite(r["psnr_db"]) and r[cost] > 0]
            if not pts:
                continue
            color, marker, name = SWEEP_STYLE[sweep]
            ax.scatter([r[cost] for r in pts], [r["psnr_db"] for r in pts],
                       color=color, marker=marker, label=name, zorder=3)
            for r in pts:
                ax.annotate(label(r), (r[cost], r["psnr_db"]), fontsize=7,
                            xytext=(3, -9), textcoords="offset points")
            everything += [(r[cost], r["psnr_db"]) for r in pts]
        front = pareto_front(everything)
        if front:
            ax.plot([p[0] for p in front], [p[1] for p in front], "k--", alpha=0.6,
                    label="Pareto front", zorder=2)
        ax.set_xscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("PSNR vs reference (dB)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"{scene}: quality against cost (labels: spp, or spp/contrast)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_depth(rows, scene, out):
    pts = of(rows, "depth")
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    depths = [r["max_depth"] for r in pts]
    psnr = [r["psnr_db"] if math.isfinite(r["psnr_db"]) else math.nan for r in pts]
    ax.plot(depths, psnr, "^-", color="tab:green", label="PSNR vs deepest")
    ax.set_xlabel("max ray-tree depth (eye ray = 1)")
    ax.set_ylabel("PSNR vs deepest render (dB)", color="tab:green")
    ax.grid(True, alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(depths, [r["seconds"] for r in pts], "o--", color="tab:purple", label="time")
    ax2.set_ylabel("render time (s)", color="tab:purple")
    ax.set_title(f"{scene}: ray-tree depth (identical deepest render = inf dB, not drawn)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv):
    if len(argv) != 3:
        sys.exit(__doc__)
    csv_path, out_dir = argv[1], argv[2]
    rows = load(csv_path)
    scene = rows[0]["scene"]
    os.makedirs(out_dir, exist_ok=True)
    plots = [("error_vs_time.png", plot_error_vs_time), ("pareto.png", plot_pareto)]
    if of(rows, "depth"):
        plots.append(("depth.png", plot_depth))
    for name, draw in plots:
        draw(rows, scene, os.path.join(out_dir, name))
        print(name)


if __name__ == "__main__":
    main(sys.argv)
