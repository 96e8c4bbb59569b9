#!/usr/bin/env python3
"""How much of a denoised NLOS capture should a reconstruction take? (issue 43)

For scenes/nlos_T.xml at each total spp n, two independent half captures A and B
(n/2 spp each, different seeds) and their merge F (n spp) are rendered and denoised
with tstat's NLOS defaults. For each reconstruction method L, the blend
H_beta = D + beta (N - D) of the denoised capture D and the noisy one N is studied:

1. the oracle: with the reference capture H (--ref-spp), the error energies
   S = ||L e_N||^2, E_D = ||L e_D||^2, C = <L e_N, L e_D>, D2 = ||L(N - D)||^2 of F and
   the best beta* = 1 - (S - C) / D2 (the error is a parabola in beta);
2. cross-validation: beta chosen on the halves, minimising ||L(D_A + b (N_A - D_A)) - L N_B||^2
   (N_B independent of A, so this is the half's error up to a constant), averaged
   with A and B swapped, then applied to F.
Energies and inner products come from reconstructions of signed captures passed as
`--denoised` volumes (<a, b> = (||a + b||^2 - ||a - b||^2) / 4): exact for bp (linear)
and for fbp and pf (magnitudes of a linear field); for fk (|.|^2 of a field of |H|) and
lct (clamped at 0) they are of the outputs, an approximation.

    python3 scripts/nlos_shrink_study.py [--spp 8,32,128,512] [--methods bp,fbp,pf,fk,lct]
        [--ref-spp 4096] [--out docs/results/nlos_shrink.md]

Not run by CI (minutes).
"""
import argparse, os, subprocess, sys, tempfile
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VOL = ["--volume=-1,1,-1,1,0.5,1.5", "--voxels", "41,41,21"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tstat", default=os.path.join(ROOT, "target/release/tstat"))
    ap.add_argument("--spp", default="8,32,128,512")
    ap.add_argument("--methods", default="bp,fbp,pf,fk,lct")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--wl-mean", default="0.2")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs/results/nlos_shrink.md"))
    a = ap.parse_args()
    T, scene = a.tstat, os.path.join(ROOT, "scenes/nlos_T.xml")
    tmp = tempfile.mkdtemp(prefix="nlos_shrink_")

    def run(args):
        r = subprocess.run(args, capture_output=True, text=True)
        if r.returncode:
            sys.exit(f"failed: {' '.join(args)}\n{r.stderr}")

    def recon(bundle, m, h=None):
        extra = ["--wl-mean", a.wl_mean] if m in ("fbp", "pf") else []
        if h is not None:
            np.save(os.path.join(tmp, "h.npy"), h.astype(np.float32)[..., None])
            extra += ["--denoised", os.path.join(tmp, "h.npy")]
        out = os.path.join(tmp, "v.npy")
        run([T, "nlos", "reconstruct", bundle, "--method", m, *VOL, "--out", out, "--force", *extra])
        return np.load(out).astype(np.float64)

    def capture(b, n):
        return np.load(os.path.join(b, "x1.npy")).sum(-1) / n

    def denoised(b):
        d = os.path.join(tmp, "d.npy")
        run([T, "denoise", b, "--out", d, "--force"])
        return np.load(d).sum(-1)

    ref = os.path.join(tmp, "ref.tstats")
    run([T, "render", scene, "--out", ref, "--spp", str(a.ref_spp), "--seed", "1"])
    H = capture(ref, a.ref_spp)
    methods = a.methods.split(",")
    rel = lambda x, r: float(np.linalg.norm(x - r) / np.linalg.norm(r))
    rows = []
    for spp in [int(s) for s in a.spp.split(",")]:
        half = spp // 2
        A, B, F = (os.path.join(tmp, f"{k}.tstats") for k in "ABF")
        run([T, "render", scene, "--out", A, "--spp", str(half), "--seed", str(1000 + spp), "--force"])
        run([T, "render", scene, "--out", B, "--spp", str(half), "--seed", str(2000 + spp), "--force"])
        run([T, "merge", A, B, "--out", F, "--force"])
        NA, NB, NF = capture(A, half), capture(B, half), capture(F, 2 * half)
        DA, DB, DF = denoised(A), denoised(B), denoised(F)
        for m in methods:
            E = lambda x: float(np.sum(recon(F, m, x) ** 2))
            dot = lambda x, y: (E(x + y) - E(x - y)) / 4
            eN, eD = NF - H, DF - H
            S, ED, C, D2 = E(eN), E(eD), dot(eN, eD), E(NF - DF)
            star = 1 - (S - C) / D2
            betas = []
            for Dx, Nx, Ny in ((DA, NA, NB), (DB, NB, NA)):
                u, v = Dx - Ny, Nx - Dx
                betas.append(min(1.0, max(0.0, -dot(u, v) / E(v))))
            beta = float(np.mean(betas))
            v_ref = recon(ref, m)
            en = rel(recon(F, m, NF), v_ref)
            ed = rel(recon(F, m, DF), v_ref)
            eo = rel(recon(F, m, DF + min(1, max(0, star)) * (NF - DF)), v_ref)
            ecv = rel(recon(F, m, DF + beta * (NF - DF)), v_ref)
            rows.append((spp, m, en, ed, eo, ecv, star, beta, S, C, ED, D2))
            print(*rows[-1], flush=True)
    lines = ["# Shrinking a denoised NLOS capture toward the noisy one, per reconstruction", "",
             f"Command: `python3 scripts/nlos_shrink_study.py --spp {a.spp} --methods {a.methods} --ref-spp {a.ref_spp}`.",
             "Scene `scenes/nlos_T.xml` (confocal 32 x 32, 512 bins); volume 41 x 41 x 21 over [-1, 1]^2 x [0.5, 1.5]; "
             f"fbp and pf with wl_mean {a.wl_mean}. Each row's capture F is the merge of two independent halves A and B. "
             f"Errors: relative L2 against the reconstruction of a {a.ref_spp}-spp capture. "
             "beta* is the oracle (from the reference), cv the beta chosen by cross-validation between the halves "
             "(module docstring); 'gain' is the noisy error over the cross-validated blend's.", "",
             "| spp | method | noisy | denoised | oracle blend | cv blend | gain (cv) | beta* | beta (cv) | S | C | E_D | D2 |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for spp, m, en, ed, eo, ecv, star, beta, S, C, ED, D2 in rows:
        lines.append(f"| {spp} | {m} | {en:.3f} | {ed:.3f} | {eo:.3f} | {ecv:.3f} | {en / ecv:.2f} | {star:.3f} | {beta:.3f} "
                     f"| {S:.3e} | {C:.3e} | {ED:.3e} | {D2:.3e} |")
    open(a.out, "w").write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
