#!/usr/bin/env python3
"""What tstat's filter loses on the published pipeline's arrays: the five arrays its
renderer returns (linear video, estimands and their variance in Yeo-Johnson 0.5, albedo,
normals) against the bundle they came from, which also gives the emitter G-buffer
(tstat's emitter class) and camera depth (its bin alignment). RMSE against a
high-spp reference of another seed, as a fraction of the noisy render's.

    pip install .            # the tstat package
    python3 scripts/arrays_cost.py [--out docs/results/arrays_cost.md]
"""
import argparse
import os
import sys
import time

import numpy as np

import tstat

ap = argparse.ArgumentParser()
ap.add_argument("--scenes", default="cbox.xml,cbox_spheres.xml")
ap.add_argument("--spp", default="8,32,128")
ap.add_argument("--reference-spp", type=int, default=4096)
ap.add_argument("--out")
a = ap.parse_args()
root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
film = dict(width=64, bins=150, bin_width_opl=0.08, pixel_sampling="independent", progress=False)
lines = [
    "| scene | spp | noisy RMSE | tstat, bundle | tstat, five arrays | + emitter | + depth | published, five arrays |",
    "|---|---|---|---|---|---|---|---|",
]
for name in a.scenes.split(","):
    scene = os.path.join(root, "scenes", name)
    start = time.time()
    ref = tstat.render(scene, a.reference_spp, seed=1000003, **film).mean().astype(np.float64)
    print(f"{name}: reference in {time.time() - start:.0f} s", file=sys.stderr)
    for spp in map(int, a.spp.split(",")):
        b = tstat.render(scene, spp, seed=7, transform="yeo-johnson:0.5", **film)
        arr = b.published_arrays()
        args = (arr["noisy"], arr["estimands"], arr["estimands_variance"], spp, arr["albedo"], arr["normals"])
        rmse = lambda v: float(np.sqrt(np.mean((v.astype(np.float64) - ref) ** 2)))
        noisy = rmse(arr["noisy"])
        full = rmse(tstat.denoise(b))
        five = rmse(tstat.denoise_arrays(*args))
        g = b.gbuffers()
        with_emitter = rmse(tstat.denoise_arrays(*args, emitter=g["emitter"]))
        with_depth = rmse(tstat.denoise_arrays(*args, depth=g["depth"], bin_width_opl=film["bin_width_opl"]))
        pub = rmse(tstat.denoise_arrays(*args, method="published"))
        lines.append(f"| {name} | {spp} | {noisy:.4e} | {full / noisy:.3f} | {five / noisy:.3f} | {with_emitter / noisy:.3f} | {with_depth / noisy:.3f} | {pub / noisy:.3f} |")
        print(lines[-1], file=sys.stderr)
text = "\n".join(lines) + "\n"
print(text)
if a.out:
    with open(a.out, "w") as f:
        f.write(
            "# tstat's filter on the published pipeline's arrays\n\n"
            "`python3 scripts/arrays_cost.py --out docs/results/arrays_cost.md`: 64x64 px, 150 bins of "
            "0.08, independent sampling, Yeo-Johnson 0.5; RMSE against a "
            f"{a.reference_spp}-spp reference of another seed, as a fraction of the noisy RMSE. "
            "\"bundle\": `tstat denoise` of the bundle (bit for bit the arrays with tstat's extras); "
            "\"five arrays\": without the emitter G-buffer and depth; \"+ emitter\", \"+ depth\": the five "
            "arrays and one of them.\n\n" + text
        )
