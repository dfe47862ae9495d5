#!/usr/bin/env python3
"""What `render --adaptive` costs in error, beside Rayshade's adaptive sampler.

For each SPD paper scene: rayfarm's adaptive render, its 16-spp render and
its 64-spp reference; with --rayshade, also Rayshade's default (adaptive)
render and its own 64-spp reference (`-S 8`, every pixel supersampled).
Each tracer's images are compared with its own reference: RMS of 8-bit
values / 255 (both tracers write 8-bit images), and eye rays per pixel
from each tracer's statistics (and rayfarm's mirror rays per pixel). A
benchmark, not a test: it prints numbers.

  scripts/adaptive-error.py build/rayfarm --rayshade PATH/rayshade \\
      --rayshade-inputs PATH/rayshade-inputs      # NAME-N.ray.gz per scene

--cutoff W prunes rayfarm's adaptive render (`render --cutoff W`) as
Rayshade's default prunes its own; the 64-spp reference stays the full ray
tree, so the error counts what the pruning leaves out. (Rayshade's error is
against its own pruned 64-spp image, so its pruning is not counted.)
"""
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import zlib

from rayshade_peer import argument_parser, parse_arguments, unpack_input

HERE = os.path.dirname(os.path.abspath(__file__))


def read_png(path):
    """8-bit RGB PNG rows without filters, as rayfarm writes them (tracer/png_file.h)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG file")
    pos, idat, size = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        pos += 12 + n
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            if (depth, colour) != (8, 2):
                sys.exit(f"{path}: expected 8-bit RGB, got depth {depth}, colour type {colour}")
            size = (w, h)
        elif kind == b"IDAT":
            idat += body
    w, h = size
    raw = zlib.decompress(idat)
    stride = 3 * w + 1
    rows = []
    for y in range(h):
        if raw[y * stride] != 0:
            sys.exit(f"{path}: row {y} uses PNG filter {raw[y * stride]}; expected none")
        rows.append(raw[y * stride + 1:(y + 1) * stride])
    return w, h, b"".join(rows)


def read_mtv(path):
    """Rayshade's MTV image: a "width height" line, then 8-bit RGB."""
    data = open(path, "rb").read()
    line_end = data.index(b"\n")
    w, h = map(int, data[:line_end].split())
    return w, h, data[line_end + 1:line_end + 1 + 3 * w * h]


def rms_error(path, reference):
    read = read_mtv if path.endswith(".mtv") else read_png
    a, b = read(path), read(reference)
    if a[:2] != b[:2]:
        sys.exit(f"{path} is {a[0]}x{a[1]}, {reference} {b[0]}x{b[1]}")
    squares = sum((x - y) ** 2 for x, y in zip(a[2], b[2]))
    return math.sqrt(squares / len(a[2])) / 255


def run(cmd):
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"failed ({done.returncode}): {' '.join(cmd)}\n{done.stderr}")
    return done.stdout + done.stderr


def rayfarm_images(exe, scene, size, contrast, cutoff, tmp):
    """Error of the adaptive and the 16-spp render against 64 spp, and the adaptive eye and mirror rays per pixel."""
    nff = os.path.join(HERE, "..", "scenes", scene + ".nff")
    out = {}
    for name, flags in (("ref", ["--spp", "64"]), ("spp16", ["--spp", "16"]),
                        ("adaptive", ["--spp", "16", "--adaptive", str(contrast), "--cutoff", str(cutoff)])):
        out[name] = os.path.join(tmp, f"rf_{scene}_{name}.png")
        stats = os.path.join(tmp, f"rf_{scene}_{name}.json")
        run([exe, "render", nff, "-o", out[name], "--width", str(size), "--height", str(size), "--stats", stats] + flags)
    rays = json.load(open(os.path.join(tmp, f"rf_{scene}_adaptive.json")))["rays"]
    return (rms_error(out["adaptive"], out["ref"]), rays["eye"] / size ** 2, rays["reflection"] / size ** 2,
            rms_error(out["spp16"], out["ref"]))


def rayshade_images(exe, inputs, scene, size, tmp):
    """Error of Rayshade's default (adaptive) render against its 64-spp render, and its eye rays per pixel."""
    ray = unpack_input(inputs, scene, tmp)
    ref, adaptive = os.path.join(tmp, f"rs_{scene}_ref.mtv"), os.path.join(tmp, f"rs_{scene}_adaptive.mtv")
    resolution = ["-R", str(size), str(size)]
    run([exe, "-q", "-S", "8", "-T", "-0.5", "-0.5", "-0.5", "-O", ref] + resolution + [ray])
    log = run([exe, "-O", adaptive] + resolution + [ray])
    eye = re.search(r"Eye rays:\s+(\d+)", log)
    if not eye:
        sys.exit(f"no eye-ray count in Rayshade's statistics for {scene}")
    return rms_error(adaptive, ref), int(eye.group(1)) / size ** 2


def main():
    ap = argument_parser(__doc__)
    ap.add_argument("--contrast", type=float, default=0.1, help="rayfarm's --adaptive contrast (default 0.1)")
    ap.add_argument("--cutoff", type=float, default=0.0,
                    help="rayfarm's --cutoff for the adaptive render (default 0: the full tree)")
    a = parse_arguments(ap)
    if not 0 <= a.cutoff <= 1:
        ap.error("--cutoff must be between 0 and 1")
    print(f"RMS error against each tracer's own 64-spp image, {a.size}x{a.size}, "
          f"rayfarm --adaptive {a.contrast} --cutoff {a.cutoff} (its reference: the full tree)")
    header = "scene   rayfarm adaptive  eye/px  mirror/px  rayfarm 16 spp"
    print(header + ("  Rayshade adaptive  eye/px" if a.rayshade else ""), flush=True)
    tmp = tempfile.mkdtemp(prefix="rayfarm-adaptive-error-")
    try:
        for scene in a.scenes:
            err, eye, mirror, err16 = rayfarm_images(a.rayfarm, scene, a.size, a.contrast, a.cutoff, tmp)
            line = f"{scene:<7} {err:16.4f}  {eye:6.2f}  {mirror:9.2f}  {err16:14.4f}"
            if a.rayshade:
                rs_err, rs_eye = rayshade_images(a.rayshade, a.rayshade_inputs, scene, a.size, tmp)
                line += f"  {rs_err:17.4f}  {rs_eye:6.2f}"
            print(line, flush=True)
    finally:
        shutil.rmtree(tmp)


if __name__ == "__main__":
    main()
