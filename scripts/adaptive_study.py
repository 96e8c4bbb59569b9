#!/usr/bin/env python3
"""Adaptive against uniform sampling at the same mean spp, noisy and denoised.

    python3 scripts/adaptive_study.py SCENE.xml REFERENCE.tstats [--spp 64,256] [--seeds 3]
        [--film 64,150,0.08] [--measures mse,relmse] [--out docs/results/adaptive_X.md]

For each spp and seed: `tstat render` uniform (Sobol', the default) and with `--adaptive`
(each error measure asked), then `tstat export` (noisy) and `tstat denoise` (default
method). Errors against the reference bundle's mean (an independent-sampling render;
its own variance of the mean is subtracted from each squared error, as
scripts/peer_samplers.py does): RMSE over all voxels, the pixels that see the light
(the reference's emitter G-buffer > 0) and the rest, and relMSE ((x - ref)^2 /
(ref^2 + 0.01), the report's). Time: the manifest's render seconds plus the pilot's
(adaptive), plus the denoiser's. Printed as Markdown (and written to --out).

Not part of CI (needs a reference bundle; minutes per scene).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TSTAT = os.path.join(ROOT, "target", "release", "tstat")
REL_EPS = 1e-2


def run(*args):
    r = subprocess.run([TSTAT, *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"tstat {' '.join(args)} failed:\n{r.stderr}")
    return r.stderr + r.stdout


def load_reference(bundle, tmp):
    """The reference's mean (f64), its emitter mask and its own variance of the mean
    per voxel, from X1 and X2 and each pixel's samples (an independent-sampling
    reference; adaptive references put their samples where the error is)."""
    ref_npy = os.path.join(tmp, "ref.npy")
    run("export", bundle, "--out", ref_npy, "--force")
    mean = np.load(ref_npy).astype(np.float64)
    light = np.load(os.path.join(bundle, "emitter.npy")) > 0
    m = json.load(open(os.path.join(bundle, "manifest.json")))
    n = np.full(light.shape, m["spp"], dtype=np.float64)
    if os.path.exists(os.path.join(bundle, "pixel_spp.npy")):
        n = np.load(os.path.join(bundle, "pixel_spp.npy")).astype(np.float64)
    n = n[:, :, None, None]
    x1 = np.load(os.path.join(bundle, "x1.npy"))
    x2 = np.load(os.path.join(bundle, "x2.npy"))
    return mean, light, np.maximum(x2 / n - (x1 / n) ** 2, 0) / (n - 1)


def errors(x, ref, ref_var, light):
    d2 = (x.astype(np.float64) - ref) ** 2 - ref_var
    out = {"all": np.sqrt(max(d2.mean(), 0.0))}
    for name, mask in (("light", light), ("rest", ~light)):
        out[name] = np.sqrt(max(d2[mask].mean(), 0.0)) if mask.any() else float("nan")
    out["relmse"] = float((d2 / (ref ** 2 + REL_EPS)).mean())
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("reference")
    ap.add_argument("--spp", default="64,256")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--film", default="64,150,0.08")
    ap.add_argument("--measures", default="mse,relmse")
    ap.add_argument("--out")
    a = ap.parse_args()
    res, bins, width = a.film.split(",")
    film = ["--width", res, "--bins", bins, "--bin-width-opl", width]
    tmp = tempfile.mkdtemp()
    ref, light, ref_var = load_reference(a.reference, tmp)
    light = np.broadcast_to(light[:, :, None, None], ref.shape)
    modes = [("uniform", [])] + [(f"adaptive {m}", ["--adaptive", "--adaptive-measure", m])
                                 for m in a.measures.split(",")]
    rows = []
    for spp in [int(s) for s in a.spp.split(",")]:
        for mode, flags in modes:
            acc = {k: [] for k in ("noisy", "denoised")}
            for seed in range(1, a.seeds + 1):
                b = os.path.join(tmp, "t.tstats")
                run("render", a.scene, "--out", b, "--spp", str(spp), "--seed", str(seed),
                    *film, *flags, "--force")
                m = json.load(open(os.path.join(b, "manifest.json")))
                seconds = m["render_seconds"] + m.get("adaptive", {}).get("pilot_seconds", 0.0)
                noisy = os.path.join(tmp, "n.npy")
                run("export", b, "--out", noisy, "--force")
                e = errors(np.load(noisy), ref, ref_var, light)
                e["seconds"] = seconds
                acc["noisy"].append(e)
                den = os.path.join(tmp, "d.npy")
                log = run("denoise", b, "--out", den, "--force")
                dsec = float(log.split(" in ")[1].split(" s")[0]) if " in " in log else 0.0
                e = errors(np.load(den), ref, ref_var, light)
                e["seconds"] = seconds + dsec
                acc["denoised"].append(e)
            for kind, es in acc.items():
                mean = {k: float(np.mean([e[k] for e in es])) for k in es[0]}
                rows.append((spp, mode, kind, mean))
                print(spp, mode, kind, json.dumps(mean), flush=True)
    lines = [f"Scene `{os.path.relpath(a.scene, ROOT)}`, film {a.film}, reference "
             f"`{a.reference}`, {a.seeds} seeds; `python3 scripts/adaptive_study.py "
             f"{' '.join(sys.argv[1:])}`.", "",
             "| spp | sampling | output | RMSE all | light | rest | relMSE | seconds | RMSE vs uniform | relMSE vs uniform |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    base = {(s, k): e for s, mo, k, e in rows if mo == "uniform"}
    for spp, mode, kind, e in rows:
        u = base[(spp, kind)]
        lines.append(
            f"| {spp} | {mode} | {kind} | {e['all']:.4e} | {e['light']:.4e} | {e['rest']:.4e} | "
            f"{e['relmse']:.4e} | {e['seconds']:.2f} | {e['all'] / u['all']:.3f} | "
            f"{e['relmse'] / u['relmse']:.3f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
