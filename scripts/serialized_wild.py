#!/usr/bin/env python3
"""Check tstat's `.serialized` loader on the real files in ../shared/wild-scenes.

Prints every mesh of every `.serialized` file found (version, name, vertex and triangle
counts, through `examples/serialized_info.rs`), then renders mitsuba-data's matpreview
scene (three meshes of one file, picked by shape_index) with its environment map (not
supported by tstat) replaced by a point light, and prints the steady image's mean.

    python3 scripts/serialized_wild.py [--wild ../shared/wild-scenes] [--keep DIR]

Not part of `cargo test`: a clone of the repository has no ../shared.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--wild", default=os.path.join(ROOT, "..", "shared", "wild-scenes"))
    ap.add_argument("--keep", help="leave the render in this directory")
    args = ap.parse_args()

    files = sorted(
        os.path.join(d, f)
        for d, _, fs in os.walk(args.wild)
        for f in fs
        if f.endswith(".serialized")
    )
    if not files:
        sys.exit(f"no .serialized files under {args.wild}")
    info = subprocess.run(
        ["cargo", "run", "--quiet", "--release", "--example", "serialized_info", "--", *files],
        cwd=ROOT,
    )
    if info.returncode != 0:
        sys.exit("some files did not load")

    scene = os.path.join(
        args.wild, "mitsuba-renderer_mitsuba-data", "scenes", "matpreview", "matpreview_transient.xml"
    )
    if not os.path.exists(scene):
        print("matpreview scene not found; render skipped")
        return
    work = args.keep or tempfile.mkdtemp()
    os.makedirs(work, exist_ok=True)
    text = open(scene, encoding="utf-8").read()
    text = re.sub(
        r'<emitter type="envmap".*?</emitter>',
        '<emitter type="point"><point name="position" x="3.7" y="-3.5" z="6"/>'
        '<rgb name="intensity" value="60"/></emitter>',
        text,
        flags=re.S,
    )
    open(os.path.join(work, "matpreview.xml"), "w", encoding="utf-8").write(text)
    shutil.copy(os.path.join(os.path.dirname(scene), "matpreview.serialized"), work)
    tstat = os.path.join(ROOT, "target", "release", "tstat")
    out = os.path.join(work, "mp.tstats")
    subprocess.run(
        [tstat, "render", os.path.join(work, "matpreview.xml"), "--out", out,
         "--width", "171", "--height", "128", "--spp", "16", "--force"],
        check=True,
    )
    steady = os.path.join(work, "steady.npy")
    subprocess.run([tstat, "export", out, "--steady", steady, "--force"], check=True)
    try:
        import numpy as np

        a = np.load(steady)
        print(f"steady image {a.shape}: mean {a.mean():.4f}, max {a.max():.4f}")
    except ImportError:
        print(f"steady image written to {steady}")
    if not args.keep:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
