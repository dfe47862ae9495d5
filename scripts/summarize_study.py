#!/usr/bin/env python3
"""One table over several scenes' accuracy studies (make study-paper).

Usage: summarize_study.py OUT_DIR SCENE...

Reads OUT_DIR/<scene>/study.csv and prints Markdown: per scene the SPD setting
(16 spp, depth 5) and every preset row, each as time (s) / PSNR (dB), and the
cheapest row of the whole study that reaches 30, 35 and 40 dB. Only reads the
CSVs, which hold every number, the Pareto fronts included.
"""
import csv
import math
import os
import sys


def load(path):
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["sweep"] != "reference"]
    for r in rows:
        r["seconds"] = float(r["seconds"])
        r["psnr"] = float(r["psnr_db"]) if r["psnr_db"] else math.nan
    return rows


def cell(row):
    return f"{row['seconds']:.2f} s / {row['psnr']:.1f} dB" if row else "-"


def cheapest(rows, psnr):
    ok = [r for r in rows if r["psnr"] >= psnr]
    return min(ok, key=lambda r: r["seconds"]) if ok else None


def name(row):
    return f"{row['sweep']} {row['value']}" if row else ""


def main(argv):
    if len(argv) < 3:
        sys.exit(__doc__)
    out, scenes = argv[1], argv[2:]
    studies = {s: load(os.path.join(out, s, "study.csv")) for s in scenes}
    presets = []
    for rows in studies.values():
        for r in rows:
            if r["sweep"] == "preset" and r["value"] not in presets:
                presets.append(r["value"])
    size = next(iter(studies.values()))[0]
    print(f"Image {size['width']}x{size['height']}; time / PSNR against the reference.\n")
    print("| scene | SPD: 16 spp, depth 5 | " + " | ".join(f"`{p}`" for p in presets) + " |")
    print("|---|---:|" + "---:|" * len(presets))
    for s, rows in studies.items():
        spd = next((r for r in rows if r["spd"] == "1"), None)
        by_preset = {r["value"]: r for r in rows if r["sweep"] == "preset"}
        print(f"| {s} | {cell(spd)} | " + " | ".join(cell(by_preset.get(p)) for p in presets) + " |")
    print("\nThe fastest render of each study that reaches a PSNR:\n")
    print("| scene | 30 dB | 35 dB | 40 dB |")
    print("|---|---|---|---|")
    for s, rows in studies.items():
        cells = []
        for target in (30, 35, 40):
            r = cheapest(rows, target)
            cells.append(f"{name(r)}: {cell(r)}" if r else "-")
        print(f"| {s} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv)
