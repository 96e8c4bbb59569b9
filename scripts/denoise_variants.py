#!/usr/bin/env python3
"""The denoiser's error under other settings, on adaptive renders of one scene (issue 42).

    python3 scripts/denoise_variants.py SCENE.xml REFERENCE.tstats SPP [--seeds 2]
        [--tstat PATH] "--radius 5" "--t2-max 16" ...

Renders SCENE at SPP mean samples a pixel (`--sampler sobol --adaptive`, 64x64 px,
150 bins of 0.08 OPL, seeds 1..N), denoises each render with the default settings and
with each variant (extra `tstat denoise` flags), and prints RMSE over all voxels and
over the pixels that do not see the light, and relMSE, against REFERENCE (its own
variance subtracted, as scripts/peer_samplers.py does), averaged over the seeds, with
each variant's ratio to the default. Not run by CI.
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sampler_error import load_reference  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("reference")
    ap.add_argument("spp", type=int)
    ap.add_argument("variants", nargs="*")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--tstat", default=os.path.join(ROOT, "target", "release", "tstat"))
    a = ap.parse_args()
    tmp = tempfile.mkdtemp()
    ref, light, ref_var = load_reference(a.reference, tmp)
    film = "-D res=64 -D temporal_bins=150 -D bin_width_opl=0.08".split()
    res = {}
    for seed in range(1, a.seeds + 1):
        b = os.path.join(tmp, f"b{seed}.tstats")
        subprocess.run([a.tstat, "render", a.scene, "--out", b, "-D", f"spp={a.spp}", *film,
                        "--sampler", "sobol", "--adaptive", "--seed", str(seed), "--force"],
                       check=True, capture_output=True)
        for v in [""] + a.variants:
            out = os.path.join(tmp, "d.npy")
            subprocess.run([a.tstat, "denoise", b, "--out", out, "--force", *v.split()],
                           check=True, capture_output=True)
            d = (np.load(out).astype(np.float64) - ref) ** 2 - ref_var
            res.setdefault(v, []).append([d.mean(), d[~light].mean(), (d / (ref ** 2 + 1e-2)).mean()])
    base = np.mean(res[""], axis=0)
    for v, r in res.items():
        r = np.mean(r, axis=0)
        print(f"{v or 'default':36s} RMSE all {np.sqrt(max(r[0], 0)):.3e} rest {np.sqrt(max(r[1], 0)):.3e} "
              f"relMSE {r[2]:.3e}  (relMSE x{base[2] / r[2]:.2f}, rest x{np.sqrt(base[1] / r[1]):.2f})")


if __name__ == "__main__":
    main()
