#!/usr/bin/env python3
"""Denoised NLOS captures against noisy ones, per reconstruction method (issue 43).

For a capture scene at each total spp n: two independent half captures A and B
(n/2 spp, different seeds) and their merge F (`tstat merge`). Reconstructed on one
voxel grid, each against the reconstruction of a --ref-spp capture (relative L2):
- noisy: F's means;
- denoised: `tstat denoise F` (the filter alone, NLOS defaults), `--denoised`;
- cv: `tstat nlos reconstruct A --denoise-with B` (F denoised and shrunk toward its
  noisy capture by the cross-validated b, docs/nlos.md).

    python3 scripts/nlos_denoise_cv.py --scene scenes/nlos_T.xml [-D key=value ...]
        --volume=-1,1,-1,1,0.5,1.5 --voxels 41,41,21 [--wl-mean 0.2]
        [--methods bp,fbp,pf,fk,lct] [--spp 4,16,64,256] [--ref-spp 4096]
        [--out docs/results/nlos_denoise_cv.md --append]

Appends (or writes) a Markdown table to --out. Not run by CI (minutes).
"""
import argparse, os, subprocess, sys, tempfile
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tstat", default=os.path.join(ROOT, "target/release/tstat"))
    ap.add_argument("--scene", required=True)
    ap.add_argument("-D", action="append", default=[], dest="defines")
    ap.add_argument("--volume", required=True)
    ap.add_argument("--voxels", required=True)
    ap.add_argument("--wl-mean", default="0.2")
    ap.add_argument("--methods", default="bp,fbp,pf,fk,lct")
    ap.add_argument("--spp", default="4,16,64,256")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs/results/nlos_denoise_cv.md"))
    ap.add_argument("--append", action="store_true")
    a = ap.parse_args()
    T = a.tstat
    defs = [x for d in a.defines for x in ("-D", d)]
    vol = [f"--volume={a.volume}", "--voxels", a.voxels]
    tmp = tempfile.mkdtemp(prefix="nlos_cv_")

    def run(args):
        r = subprocess.run(args, capture_output=True, text=True)
        if r.returncode:
            sys.exit(f"failed: {' '.join(args)}\n{r.stderr}")
        return r.stderr

    def recon(bundle, m, *extra):
        wl = ["--wl-mean", a.wl_mean] if m in ("fbp", "pf") else []
        out = os.path.join(tmp, "v.npy")
        err = run([T, "nlos", "reconstruct", bundle, "--method", m, *wl, *vol, "--out", out, "--force", *extra])
        return np.load(out).astype(np.float64), err

    def render(out, spp, seed):
        run([T, "render", a.scene, *defs, "--out", out, "--spp", str(spp), "--seed", str(seed), "--force"])

    ref = os.path.join(tmp, "ref.tstats")
    render(ref, a.ref_spp, 1)
    methods = a.methods.split(",")
    v_ref = {m: recon(ref, m)[0] for m in methods}
    rel = lambda x, r: float(np.linalg.norm(x - r) / np.linalg.norm(r))
    rows = []
    for spp in [int(s) for s in a.spp.split(",")]:
        A, B, F = (os.path.join(tmp, f"{k}.tstats") for k in "ABF")
        render(A, spp // 2, 1000 + spp)
        render(B, spp // 2, 2000 + spp)
        run([T, "merge", A, B, "--out", F, "--force"])
        d = os.path.join(tmp, "d.npy")
        run([T, "denoise", F, "--out", d, "--force"])
        for m in methods:
            en = rel(recon(F, m)[0], v_ref[m])
            ed = rel(recon(F, m, "--denoised", d)[0], v_ref[m])
            v, err = recon(A, m, "--denoise-with", B)
            ecv = rel(v, v_ref[m])
            b = float(err.split("b = ")[1].split()[0])
            rows.append((spp, m, en, ed, ecv, b))
            print(*rows[-1], flush=True)
    scene = os.path.relpath(os.path.abspath(a.scene), ROOT)
    cmd = f"python3 scripts/nlos_denoise_cv.py --scene {scene} {' '.join('-D ' + d for d in a.defines)} " \
          f"--volume={a.volume} --voxels {a.voxels} --wl-mean {a.wl_mean} --methods {a.methods} --spp {a.spp} --ref-spp {a.ref_spp}"
    lines = [f"## {scene} {' '.join(a.defines)}", "", f"Command: `{' '.join(cmd.split())}`.", "",
             "| spp | method | noisy | denoised | cv (`--denoise-with`) | gain, denoised | gain, cv | b |",
             "|---|---|---|---|---|---|---|---|"]
    for spp, m, en, ed, ecv, b in rows:
        lines.append(f"| {spp} | {m} | {en:.3f} | {ed:.3f} | {ecv:.3f} | {en / ed:.2f} | {en / ecv:.2f} | {b:.3f} |")
    text = "\n".join(lines) + "\n\n"
    head = "" if a.append and os.path.exists(a.out) else (
        "# Denoised NLOS captures against noisy ones, per reconstruction\n\n"
        "Relative L2 error of each reconstruction against the reconstruction of a high-spp capture; "
        "each spp's capture is the merge of two independent halves. 'gain': the noisy error over "
        "the other's (> 1: better than noisy). b: the cross-validated weight of the noisy capture.\n\n")
    with open(a.out, "a" if a.append else "w") as f:
        f.write(head + text)
    print(text)


if __name__ == "__main__":
    main()
