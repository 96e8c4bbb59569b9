#!/usr/bin/env python3
"""Does denoising a capture give a better NLOS reconstruction for the same time?

For scenes/nlos_T.xml (confocal 32 x 32, 512 bins) at increasing spp:
1. `tstat render` (wall time t_r), and `tstat nlos reconstruct --method M` of the noisy
   capture;
2. `tstat denoise` with each filter setting (wall time t_d), and the reconstruction of
   the denoised capture (`--denoised`);
3. the error of each reconstruction, ||V - V_ref|| / ||V_ref|| (relative L2 over the
   volume), against the reconstruction of a high-spp capture; and the error of the
   capture itself, ||H - H_ref|| / ||H_ref||.
Equal time: a denoised run costs t_r + t_d; the noisy error at that time is
interpolated (log-log) between the noisy runs; the gain is that error over the
denoised one. Reconstruction time is the same for both and left out.

    python3 scripts/nlos_denoise_study.py [--spp 4,8,...] [--ref-spp 4096]
        [--methods fbp,pf] [--out docs/results/nlos_denoise.md]

Writes the table and a plot (nlos_denoise_<method>.png) next to --out. Not run by CI.
"""
import argparse, os, subprocess, tempfile, time
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VOL = ["--volume=-1,1,-1,1,0.5,1.5", "--voxels", "41,41,21"]
# The default on NLOS captures is tstat's test, radius 1, no depth alignment.
SETTINGS = {
    "default (tstat, r 1)": [],
    "tstat, r 2": ["--radius", "2"],
    "tstat, r 3": ["--radius", "3"],
    "tstat, r 3, depth-aligned": ["--radius", "3", "--depth-align"],
    "base only, r 1": ["--no-membership", "--radius", "1"],
    "base only, r 2": ["--no-membership", "--radius", "2"],
}


def run(args):
    t = time.time()
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"failed: {' '.join(args)}\n{r.stderr}")
    return time.time() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tstat", default=os.path.join(ROOT, "target/release/tstat"))
    ap.add_argument("--spp", default="4,8,16,32,64,128,256")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--noisy-only", default="512,1024",
                    help="spp rendered noisy only, so that the noisy curve reaches the denoised runs' times")
    ap.add_argument("--methods", default="fbp,pf")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs/results/nlos_denoise.md"))
    a = ap.parse_args()
    T, scene = a.tstat, os.path.join(ROOT, "scenes/nlos_T.xml")
    tmp = tempfile.mkdtemp(prefix="nlos_denoise_")
    methods = a.methods.split(",")
    extra = {"fbp": ["--wl-mean", "0.2"], "pf": ["--wl-mean", "0.2"], "bp": [], "fk": [], "lct": []}

    def recon(bundle, m, out, denoised=None):
        d = ["--denoised", denoised] if denoised else []
        run([T, "nlos", "reconstruct", bundle, "--method", m, *extra[m], *VOL, "--out", out, "--force", *d])
        return np.load(out)

    def capture_of(bundle, denoised=None):
        if denoised:
            return np.load(denoised).sum(-1)
        m = __import__("json").load(open(os.path.join(bundle, "manifest.json")))
        return np.load(os.path.join(bundle, "x1.npy")).sum(-1) / m["spp"]

    ref = os.path.join(tmp, "ref.tstats")
    run([T, "render", scene, "--out", ref, "--spp", str(a.ref_spp), "--seed", "1"])
    v_ref = {m: recon(ref, m, os.path.join(tmp, f"ref_{m}.npy")) for m in methods}
    h_ref = capture_of(ref)
    rel = lambda x, r: float(np.linalg.norm(x - r) / np.linalg.norm(r))
    rows = []  # (spp, setting or None, time, capture err, {method: err})
    spps = [int(s) for s in a.spp.split(",")]
    noisy_only = [int(s) for s in a.noisy_only.split(",") if s]
    for i, spp in enumerate(spps + noisy_only):
        b = os.path.join(tmp, f"n{spp}.tstats")
        # Best of two renders: the bundle write makes single times noisy.
        tr = min(run([T, "render", scene, "--out", b, "--spp", str(spp), "--seed", str(100 + i), "--force"])
                 for _ in range(2))
        errs = {m: rel(recon(b, m, os.path.join(tmp, "v.npy")), v_ref[m]) for m in methods}
        rows.append((spp, None, tr, rel(capture_of(b), h_ref), errs))
        for name, args in (SETTINGS.items() if spp in spps else []):
            d = os.path.join(tmp, "d.npy")
            td = min(run([T, "denoise", b, "--out", d, "--force", *args]) for _ in range(2))
            errs = {m: rel(recon(b, m, os.path.join(tmp, "v.npy"), d), v_ref[m]) for m in methods}
            rows.append((spp, name, tr + td, rel(capture_of(b, d), h_ref), errs))
        print(spp, "done", flush=True)

    noisy = [r for r in rows if r[1] is None]

    def noisy_at(t, key):
        ts = np.log([r[2] for r in noisy])
        es = np.log([key(r) for r in noisy])
        order = np.argsort(ts)
        if t < np.exp(ts[order][0]) or t > np.exp(ts[order][-1]):
            return None
        return float(np.exp(np.interp(np.log(t), ts[order], es[order])))

    lines = ["# Denoised NLOS captures: reconstruction error against time", "",
             f"Command: `python3 scripts/nlos_denoise_study.py --spp {a.spp} --noisy-only {a.noisy_only} --ref-spp {a.ref_spp} --methods {a.methods}`.",
             "Scene `scenes/nlos_T.xml` (confocal 32 x 32, 512 bins); volume 41 x 41 x 21 over [-1, 1]^2 x [0.5, 1.5];",
             "fbp and pf with wl_mean 0.2. Error: relative L2 against the reconstruction of a "
             f"{a.ref_spp}-spp capture. Time: render (+ denoise), wall, best of two.",
             "Gain at equal time: the noisy error interpolated at the same time (render + denoise), over the denoised error "
             "(> 1: denoising wins; '-' outside the noisy runs' times). Gain at equal spp (= equal render time): the noisy "
             "error at the same spp over the denoised error.", "",
             "| spp | capture | time s | capture err | " + " | ".join(f"{m} err | {m} gain, equal time | {m} gain, equal spp" for m in methods) + " |",
             "|---|---|---|---|" + "---|---|---|" * len(methods)]
    for spp, name, t, ce, errs in rows:
        cells = []
        for m in methods:
            g = None if name is None else noisy_at(t, lambda r: r[4][m])
            same = [r for r in noisy if r[0] == spp][0][4][m]
            cells += [f"{errs[m]:.3f}", "" if name is None else ("-" if g is None else f"{g / errs[m]:.2f}"),
                      "" if name is None else f"{same / errs[m]:.2f}"]
        lines.append(f"| {spp} | {name or 'noisy'} | {t:.2f} | {ce:.3f} | " + " | ".join(cells) + " |")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    for m in methods:
        plt.figure(figsize=(6, 4))
        for name in [None, *SETTINGS]:
            pts = [(r[2], r[4][m]) for r in rows if r[1] == name]
            plt.loglog(*zip(*pts), "o-" if name is None else ".--", label=name or "noisy")
        plt.xlabel("time (s): render + denoise")
        plt.ylabel(f"{m} reconstruction error (rel. L2)")
        plt.legend(fontsize=7)
        plt.tight_layout()
        png = os.path.join(os.path.dirname(a.out), f"nlos_denoise_{m}.png")
        plt.savefig(png, dpi=100)
        plt.close()
        lines.append(f"\nPlot: `{os.path.basename(png)}`.")
    import json
    json.dump(rows, open(os.path.splitext(a.out)[0] + ".json", "w"), indent=1)
    text = "\n".join(lines) + "\n"
    open(a.out, "w").write(text)
    print(text)


if __name__ == "__main__":
    main()
