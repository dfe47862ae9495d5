#!/usr/bin/env python3
"""The paper's Figures 1-5 and a paper-vs-replay table from the output tree of
scripts/replay-paper.sh (OUT/POLICY/SCENE/{lab,lab-plain,lab-prior,ssc38-kK}/).

Usage: plot_paper_figures.py OUT SCENE [SCENE ...]

Writes OUT/fig1-task-size.png, fig2-load-38ssc.png, fig3-speedup-ssc.png,
fig4-speedup-lab.png, fig5-load-lab.png and OUT/paper-table.md (also printed).
Each figure has the paper's policy and the default (adaptive) side by side.
"""
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")  # no display on build machines
import matplotlib.pyplot as plt  # noqa: E402

POLICIES = [("paper", "paper policy (1 row, one task at a time)"), ("adaptive", "default policy (adaptive)")]
# Numbers the paper states (sections 4.3, 4.4.1): speedups and Tetra's time.
PAPER_46 = {"tetra": 22.91, "balls": 42.06, "mount": 36.56}
PAPER_85 = {"balls": 64.19, "mount": 52.72}
PAPER_TETRA_46_S = 77.06


def load_json(path):
    with open(path) as f:
        return json.load(f)


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def save(fig, out, name):
    fig.tight_layout()
    fig.savefig(os.path.join(out, name), dpi=70)
    plt.close(fig)
    print("wrote", os.path.join(out, name), file=sys.stderr)


def fig1(out, scenes):
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, (policy, title) in zip(axes, POLICIES):
        for scene in scenes:
            ks, ts = [], []
            for k in range(1, 21):
                p = os.path.join(out, policy, scene, "ssc38-k%d" % k, "replay.json")
                if os.path.exists(p):
                    ks.append(k)
                    ts.append(load_json(p)["makespan_s"])
            if len(ks) == 1:
                ks, ts = [1, 20], ts * 2  # adaptive sizes its own tasks: one value
            ax.plot(ks, ts, marker="." if policy == "paper" else None, label=scene)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("scanlines per task")
        ax.set_yscale("log")
    axes[0].set_ylabel("execution time on 38 SSCs (s)")
    axes[0].legend(fontsize=8)
    save(fig, out, "fig1-task-size.png")


def load_figure(out, scene, sub, name, title):
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, (policy, ptitle) in zip(axes, POLICIES):
        tasks = rows(os.path.join(out, policy, scene, sub, "tasks.csv"))
        xs = [int(t["machine"]) + 1 for t in tasks if t["accepted"] == "1"]
        ys = [float(t["finished"]) for t in tasks if t["accepted"] == "1"]
        ax.scatter(xs, ys, s=6, marker="o", facecolors="none", edgecolors="C0", linewidths=0.6)
        bx = [int(t["machine"]) + 1 for t in tasks if t["accepted"] != "1"]
        by = [float(t["finished"]) for t in tasks if t["accepted"] != "1"]
        if bx:
            ax.scatter(bx, by, s=8, marker="x", color="C3", linewidths=0.6, label="beaten backup / copy")
            ax.legend(fontsize=8)
        ax.set_title("%s: %s" % (title, ptitle), fontsize=9)
        ax.set_xlabel("server")
    axes[0].set_ylabel("task completion time (s)")
    save(fig, out, name)


def speedup_figure(out, scenes, series, name, xlabel):
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    paper = PAPER_46 if series == "homogeneous" else PAPER_85
    for ax, (policy, title) in zip(axes, POLICIES):
        top = 0
        for i, scene in enumerate(scenes):
            pts = [r for r in rows(os.path.join(out, policy, scene, "lab", "sweep.csv")) if r["series"] == series]
            x = [float(r["machines" if series == "homogeneous" else "normalized"]) for r in pts]
            ax.plot(x, [float(r["speedup"]) for r in pts], color="C%d" % i, label=scene)
            top = max(top, x[-1])
            if scene in paper:
                ax.plot([x[-1]], [paper[scene]], "x", color="C%d" % i, markersize=8)
        ax.plot([0, top], [0, top], "k--", linewidth=0.7)
        ax.set_title(title + " (x: the paper's number)", fontsize=9)
        ax.set_xlabel(xlabel)
    axes[0].set_ylabel("speedup")
    axes[0].legend(fontsize=8)
    save(fig, out, name)


def sweep_end(out, policy, scene, sub, series):
    """Speedup and makespan at the end of a sweep series (46 SSCs, or the whole lab)."""
    pts = [r for r in rows(os.path.join(out, policy, scene, sub, "sweep.csv")) if r["series"] == series]
    return float(pts[-1]["speedup"]), float(pts[-1]["makespan_s"]), float(pts[-1]["init_bound"])


def against_paper(replayed, paper):
    return "%.2f (%+.1f%%)" % (replayed, 100 * (replayed / paper - 1)) if paper else "%.2f" % replayed


def table(out, scenes):
    """Speedups against the paper's, with the paper's serial start-up ("lab") and
    without it ("lab-plain"), and each run's makespan over its lower bound."""
    lines = ["| scene | paper: 46 SSC | paper policy | plain model | adaptive | paper: 85 norm. | paper policy |"
             " plain model | adaptive | makespan / lower bound: paper policy | adaptive | adaptive, plain model |"
             " adaptive, prior frame |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for scene in scenes:
        cells = [scene]
        for series, paper in [("homogeneous", PAPER_46.get(scene)), ("heterogeneous", PAPER_85.get(scene))]:
            cells.append("%.2f" % paper if paper else "-")
            cells.append(against_paper(sweep_end(out, "paper", scene, "lab", series)[0], paper))
            cells.append(against_paper(sweep_end(out, "paper", scene, "lab-plain", series)[0], paper))
            cells.append("%.2f" % sweep_end(out, "adaptive", scene, "lab", series)[0])
        for p, sub in [("paper", "lab"), ("adaptive", "lab"), ("adaptive", "lab-plain"), ("adaptive", "lab-prior")]:
            cells.append("%.3f" % load_json(os.path.join(out, p, scene, sub, "replay.json"))["bound_ratio"])
        lines.append("| " + " | ".join(cells) + " |")
    if "tetra" in scenes:
        t = []
        for p, _ in POLICIES:
            for sub in ["lab", "lab-plain"]:
                _, makespan, bound = sweep_end(out, p, "tetra", sub, "homogeneous")
                t.append("%.2f s (%s%s)" % (makespan, p, ", plain model" if sub == "lab-plain" else ""))
        lines.append("")
        lines.append("Tetra on 46 SSCs: paper %.2f s; replay %s; init-time bound on speedup 70.6 (paper) vs %.1f." %
                     (PAPER_TETRA_46_S, ", ".join(t), bound))
    text = "\n".join(lines) + "\n"
    with open(os.path.join(out, "paper-table.md"), "w") as f:
        f.write(text)
    print(text)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out, scenes = sys.argv[1], sys.argv[2:]
    fig1(out, scenes)
    scene = "balls" if "balls" in scenes else scenes[0]
    load_figure(out, scene, "ssc38-k1", "fig2-load-38ssc.png", "Fig. 2, %s, 38 SSCs" % scene)
    speedup_figure(out, scenes, "homogeneous", "fig3-speedup-ssc.png", "Sun SSCs")
    speedup_figure(out, scenes, "heterogeneous", "fig4-speedup-lab.png", "machines normalised to the SSC")
    load_figure(out, scene, "lab", "fig5-load-lab.png", "Fig. 5, %s, whole lab" % scene)
    table(out, scenes)


if __name__ == "__main__":
    main()
