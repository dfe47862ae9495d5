"""What the benchmarks that run beside Rayshade share: the paper scenes' names
in both renderers, the command line that names the two executables and the
scenes, and Rayshade's inputs unpacked for a run."""
import argparse
import gzip
import os
import shutil
import sys

# rayfarm's scenes/NAME.nff and Rayshade's NAME-N.ray.gz (the SPD size N).
SCENES = {"balls": "balls-4", "gears": "gears-4", "mount": "mount-6", "rings": "rings-7", "tetra": "tetra-6"}


def argument_parser(doc):
    """A parser with the rayfarm executable, --rayshade, --rayshade-inputs, --size and --scenes."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=doc)
    ap.add_argument("rayfarm", help="path of the rayfarm executable")
    ap.add_argument("--rayshade", help="a Rayshade 4.0.6 executable (omit: rayfarm alone)")
    ap.add_argument("--rayshade-inputs", help="folder of NAME-N.ray.gz Rayshade inputs for the scenes")
    ap.add_argument("--size", type=int, default=512, help="image width and height (default 512, the paper's)")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    return ap


def parse_arguments(ap):
    a = ap.parse_args()
    if a.rayshade and not a.rayshade_inputs:
        ap.error("--rayshade needs --rayshade-inputs")
    if a.size < 1:
        ap.error("--size must be at least 1")
    return a


def unpack_input(inputs, scene, tmp):
    """Rayshade's input for scene, unpacked into tmp; its path."""
    packed = os.path.join(inputs, SCENES[scene] + ".ray.gz")
    if not os.path.isfile(packed):
        sys.exit(f"{packed}: no such Rayshade input (--rayshade-inputs names their folder)")
    ray = os.path.join(tmp, SCENES[scene] + ".ray")
    with gzip.open(packed, "rb") as src, open(ray, "wb") as dst:
        shutil.copyfileobj(src, dst)
    return ray
