#!/usr/bin/env python3
"""`tstat denoise --method published` against the published method's own code.

    python3 scripts/published_official.py --official DIR \
        [--scene scenes/cbox.xml] [--film 32,60,0.2] [--spp 32] [--seed 1] \
        [--reference REF.tstats] [--out docs/results/published_official.md]

DIR is a clone of github.com/alv02/StatisticalDenoisingTransientRendering (its
`denoisers/statTransientDenoiser.py`, class `StatDenoiser`, is imported from there and
run unmodified on the CPU; it needs `pip install torch scipy`). Not part of CI.

1. tstat renders the scene with Yeo-Johnson(0.5) sums and independent sampling, the
   published pipeline's settings.
2. The official code's inputs are made from that bundle as its renderer's
   `develop_stats` makes them (github.com/alv02/statmitransient): zero-fill, `mu = S1 /
   n`, the biased variance `var = S2 / n - mu^2` clamped at 0, `m3 = S3 / n - 3 mu var -
   mu^3`, estimand `mu + m3 / (6 var n)` (`mu` where var = 0) and its variance `var / n`;
   the noisy video `S / n` (linear radiance); albedo and normals from the bundle's
   G-buffers.
3. `StatDenoiser(spatial_radius=10, temporal_radius=1, alpha=0.1, spp=n)`, the call of
   its example notebook, denoises them.
4. tstat denoises the bundle with the same call written as tstat's flags (the recipe in
   docs/denoiser.md): `--method published --radius 10 --temporal-radius 1 --alpha 0.1
   --variance biased --border zero` and the base filter's widths that reproduce the
   code's guidance weights (`sigma_inv` 0.3 on positions spaced `size / (r (size - 1))`
   apart, 50 on albedo, 10 on normals).
5. Prints the relative L2 difference `||tstat - official|| / ||official||`, also for
   tstat's defaults (SPEC 5's unbiased variance, clipped borders) to show what each
   convention is worth, and with `--reference` each output's RMSE against it.
"""
import argparse
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TSTAT = os.path.join(ROOT, "target", "release", "tstat")


def run(*args):
    r = subprocess.run([TSTAT, *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"tstat {' '.join(args)} failed:\n{r.stderr}")
    return r.stderr + r.stdout


def official_inputs(bundle):
    """The official denoiser's inputs from a tstat bundle of Yeo-Johnson sums."""
    m = json.load(open(os.path.join(bundle, "manifest.json")))
    n = float(m["spp"])
    load = lambda f: np.load(os.path.join(bundle, f))
    s1, s2, s3 = load("x1.npy"), load("x2.npy"), load("x3.npy")
    # Yeo-Johnson: z(0) = 0, so the zero samples add nothing to the sums.
    mu = s1 / n
    var = np.maximum(s2 / n - mu ** 2, 0.0)
    m3 = s3 / n - 3 * mu * var - mu ** 3
    with np.errstate(divide="ignore", invalid="ignore"):
        estimands = np.where(var == 0, mu, mu + m3 / (6 * var * n))
    images = load("sum.npy") / n
    return (images.astype(np.float32), load("albedo.npy").astype(np.float32),
            load("normal.npy").astype(np.float32), estimands.astype(np.float32),
            (var / n).astype(np.float32), int(n))


def official_flags(h, w, t, r=10, rt=1, alpha=0.1):
    """tstat flags for the notebook's call on an h x w x t volume (square films: the
    code spaces x and y alike only when h = w)."""
    sx = r * (w - 1) / (w * math.sqrt(0.3))
    st = rt * (t - 1) / (t * math.sqrt(0.3))
    # The code's guidance is always albedo and normals (tstat's default for scenes with
    # media is the Gaussian base filter).
    return ["--method", "published", "--base", "jbf", "--radius", str(r), "--temporal-radius", str(rt),
            "--alpha", str(alpha), "--sigma-xy", repr(sx), "--sigma-t", repr(st),
            "--sigma-albedo", repr(1 / math.sqrt(50)), "--sigma-normal", repr(1 / math.sqrt(10))]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--official", required=True)
    ap.add_argument("--scene", default=os.path.join(ROOT, "scenes", "cbox.xml"))
    ap.add_argument("--film", default="32,60,0.2", help="width,bins,bin width (OPL)")
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reference")
    ap.add_argument("--out")
    a = ap.parse_args()
    spec = importlib.util.spec_from_file_location(
        "stat_denoiser", os.path.join(a.official, "denoisers", "statTransientDenoiser.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    import torch

    width, bins, bw = a.film.split(",")
    tmp = tempfile.mkdtemp()
    b = os.path.join(tmp, "b.tstats")
    run("render", a.scene, "--width", width, "--height", width, "--bins", bins,
        "--bin-width-opl", bw, "--spp", str(a.spp), "--seed", str(a.seed),
        "--transform", "yeo-johnson:0.5", "--pixel-sampling", "independent", "--out", b)
    images, albedo, normals, est, var, n = official_inputs(b)
    h, w, t, _ = images.shape
    with torch.no_grad():
        den = mod.StatDenoiser(spatial_radius=10, temporal_radius=1, alpha=0.1, spp=n)
        official = den(images, albedo, normals, est, var).numpy().astype(np.float64)

    rows = []
    base = official_flags(h, w, t)
    for label, extra in [
        ("tstat, the official call (biased variance, zero borders)", base + ["--variance", "biased", "--border", "zero"]),
        ("tstat, biased variance, clipped borders", base + ["--variance", "biased"]),
        ("tstat, unbiased variance, zero borders", base + ["--border", "zero"]),
        ("tstat, unbiased variance, clipped borders (SPEC 5, 8)", base),
        ("tstat's default method", []),
    ]:
        out = os.path.join(tmp, "d.npy")
        run("denoise", b, "--out", out, "--force", *extra)
        v = np.load(out).astype(np.float64)
        rows.append((label, np.linalg.norm(v - official) / np.linalg.norm(official), v))

    lines = [f"Scene `{os.path.relpath(a.scene, ROOT)}`, {w}x{h} px, {t} bins of {bw} OPL, "
             f"{n} spp (Yeo-Johnson 0.5, independent), seed {a.seed}. The official code: "
             "`StatDenoiser(spatial_radius=10, temporal_radius=1, alpha=0.1, spp)` on its "
             "renderer's statistics made from the same sums.", "",
             "| tstat denoise | relative L2 to the official output |", "|---|---|"]
    lines += [f"| {label} | {d:.2e} |" for label, d, _ in rows]
    if a.reference:
        ref_npy = os.path.join(tmp, "ref.npy")
        run("export", a.reference, "--out", ref_npy, "--force")
        ref = np.load(ref_npy).astype(np.float64)
        noisy = images.astype(np.float64)
        rmse = lambda v: float(np.sqrt(np.mean((v - ref) ** 2)))
        lines += ["", f"RMSE against `{os.path.basename(a.reference)}` "
                  "(as a fraction of the noisy input's):", "",
                  "| volume | RMSE | / noisy |", "|---|---|---|",
                  f"| noisy | {rmse(noisy):.4e} | 1 |",
                  f"| official | {rmse(official):.4e} | {rmse(official) / rmse(noisy):.3f} |"]
        lines += [f"| {label} | {rmse(v):.4e} | {rmse(v) / rmse(noisy):.3f} |" for label, _, v in rows]
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        open(a.out, "w").write(text)


if __name__ == "__main__":
    main()
