#!/usr/bin/env python3
"""Writes the fixture of `tests/it/denoise.rs::the_published_call_reproduces_the_official_code`:
the published method's own code (`StatDenoiser`, see scripts/published_official.py)
run on a small tstat bundle, for two calls.

    python3 scripts/make_published_fixture.py --official DIR [--out tests/data/published_official]

The bundle (cbox, 12 x 12 px, 16 bins of 0.5 OPL, 8 spp, Yeo-Johnson 0.5, independent
sampling, seed 5) is rendered into OUT/bundle.tstats; each call's output, f32
(H, W, T, 3), goes to OUT/official_r{r}_rt{rt}_a{alpha}.npy. Needs torch and scipy.
Not part of CI (CI runs the test against the files written here).
"""
import argparse
import importlib.util
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from published_official import ROOT, TSTAT, official_inputs  # noqa: E402

CALLS = [(10, 1, 0.1), (2, 2, 0.05)]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--official", required=True)
    ap.add_argument("--out", default=os.path.join(ROOT, "tests", "data", "published_official"))
    a = ap.parse_args()
    spec = importlib.util.spec_from_file_location(
        "stat_denoiser", os.path.join(a.official, "denoisers", "statTransientDenoiser.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    import torch

    os.makedirs(a.out, exist_ok=True)
    b = os.path.join(a.out, "bundle.tstats")
    subprocess.run([TSTAT, "render", os.path.join(ROOT, "scenes", "cbox.xml"), "--width", "12",
                    "--height", "12", "--bins", "16", "--bin-width-opl", "0.5", "--spp", "8",
                    "--seed", "5", "--transform", "yeo-johnson:0.5", "--pixel-sampling",
                    "independent", "--out", b, "--force"], check=True, capture_output=True)
    images, albedo, normals, est, var, n = official_inputs(b)
    for r, rt, alpha in CALLS:
        with torch.no_grad():
            out = mod.StatDenoiser(spatial_radius=r, temporal_radius=rt, alpha=alpha, spp=n)(
                images, albedo, normals, est, var).numpy().astype(np.float32)
        np.save(os.path.join(a.out, f"official_r{r}_rt{rt}_a{alpha}.npy"), out)
        print(f"r {r}, r_t {rt}, alpha {alpha}: {out.shape}")


if __name__ == "__main__":
    main()
