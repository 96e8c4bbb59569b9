#!/usr/bin/env python3
"""RMSE of tstat's sampling modes against a reference bundle, noisy and denoised.

    python3 scripts/sampler_error.py SCENE.xml SPP SEEDS REFERENCE.tstats \
        [--modes stratified,sobol,independent] [--film 64,150,0.08] [--no-denoise]

Renders SCENE at SPP with seeds 1..SEEDS in each mode (film: res, bins, bin width in
OPL, as `-D res= -D temporal_bins= -D bin_width_opl=`), exports the noisy mean and runs
`tstat denoise`, and prints the RMSE over all voxels, the pixels that see the light
(the reference's emitter G-buffer > 0) and the rest. The reference's own variance of
the mean (from its X1 and X2, valid for an independent-sampling reference) is
subtracted from each voxel's squared error, so a finite reference does not hide the
differences. Needs numpy and a release build (`cargo build --release`).
"""
import argparse
import json
import os
import subprocess
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TSTAT = os.path.join(ROOT, "target", "release", "tstat")


def run(*args):
    subprocess.run([TSTAT, *args], check=True, capture_output=True)


def load_reference(bundle, tmp):
    """The reference's mean volume (f64), its emitter mask and its own variance of the
    mean per voxel (from X1 and X2: valid for an independent-sampling reference)."""
    ref_npy = os.path.join(tmp, "ref.npy")
    run("export", bundle, "--out", ref_npy, "--force")
    mean = np.load(ref_npy).astype(np.float64)
    light = np.load(os.path.join(bundle, "emitter.npy")) > 0
    n = json.load(open(os.path.join(bundle, "manifest.json")))["spp"]
    counts = os.path.join(bundle, "pixel_spp.npy")
    if os.path.exists(counts):  # an adaptive reference: each pixel's own count
        n = np.load(counts).astype(np.float64)[:, :, None, None]
    x1 = np.load(os.path.join(bundle, "x1.npy"))
    x2 = np.load(os.path.join(bundle, "x2.npy"))
    return mean, light, np.maximum(x2 / n - (x1 / n) ** 2, 0) / (n - 1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("spp", type=int)
    ap.add_argument("seeds", type=int)
    ap.add_argument("reference")
    ap.add_argument("--modes", default="stratified,sobol")
    ap.add_argument("--film", default="64,150,0.08")
    ap.add_argument("--no-denoise", action="store_true")
    ap.add_argument("--denoise-args", default="",
                    help="extra arguments for tstat denoise, e.g. '--t2-max 9'")
    ap.add_argument("--replicates", default="0",
                    help="comma-separated replicate counts B to try with each mode (0: none)")
    a = ap.parse_args()
    res, bins, width = a.film.split(",")
    film = ["-D", f"res={res}", "-D", f"temporal_bins={bins}", "-D", f"bin_width_opl={width}"]
    tmp = tempfile.mkdtemp()
    R, light, ref_var = load_reference(a.reference, tmp)
    kinds = ["noisy"] + ([] if a.no_denoise else ["denoised"])
    for mode, reps in [(m, r) for m in a.modes.split(",") for r in a.replicates.split(",")]:
        for kind in kinds:
            mse = {"all": [], "light": [], "rest": []}
            for seed in range(1, a.seeds + 1):
                b = os.path.join(tmp, "t.tstats")
                out = os.path.join(tmp, "t.npy")
                run("render", a.scene, "--out", b, "-D", f"spp={a.spp}", *film,
                    "--pixel-sampling", mode, "--replicates", reps, "--seed", str(seed), "--force")
                if kind == "noisy":
                    run("export", b, "--out", out, "--force")
                else:
                    run("denoise", b, "--out", out, "--force", *a.denoise_args.split())
                d = (np.load(out).astype(np.float64) - R) ** 2 - ref_var
                mse["all"].append(d.mean())
                mse["light"].append(d[light].mean())
                mse["rest"].append(d[~light].mean())
            print(mode, f"B={reps}", kind, a.spp, " ".join(
                f"{k} {np.sqrt(max(np.mean(v), 0)):.3e}" for k, v in mse.items()))


if __name__ == "__main__":
    main()
