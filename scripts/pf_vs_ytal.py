#!/usr/bin/env python3
"""tstat's phasor-field reconstruction against y-tal 0.20's `tal.reconstruct.pf_dev`.

1. `tstat render scenes/nlos_T_exhaustive.xml --start-opl 0 --bins 1024` (8 x 8 laser x
   8 x 8 sensor points on a 2 x 2 wall in z = 0, the letter T at depth 1), `tstat
   export --tal`.
2. `tal.reconstruct.pf_dev.solve(data, wl_mean, wl_sigma = wl_mean / sqrt(2),
   volume_xyz = V, camera_system = DIRECT_LIGHT)` and `tstat nlos reconstruct CAPTURE
   --method pf --wl-mean W` on the same voxels; tstat writes the magnitude, compared
   with y-tal's |complex|: max |difference| / max |y-tal| (target <= 1e-3), and both
   times (y-tal's solve; tstat's whole process).
   - "volume": y-tal's 41 x 41 x 21 volume of [-1, 1]^2 x [0.5, 1.5] (finer than the
     wall's grid: both sum directly, y-tal's `divide_volume`);
   - "slice": one 8 x 8 slice at z = 1 over the wall grid's points (spacing 0.25):
     both propagate by FFT convolution (y-tal's `divide_frequencies`).

y-tal 0.20's pf_dev has four faults this script steps around: it needs `nt` passed
(`nf = nt + 2 padding` with nt None otherwise), it fails whenever t_start != 0
(`invsq_14.reshape` on an int), so the capture starts at OPL 0; its convolution
path fails on volumes of more than one slice (it reshapes the whole volume as one
slice), so the convolution case is one slice; and that path is right only when the
slice has as many points per axis as the wall's grid (it centres the kernel with
`ifftshift`, a shift of floor((NX + Sx - 1) / 2), where the linear convolution needs
Sx - 1: with a 24 x 24 slice over this 8 x 8 wall its peak lands 6 cells off, max
rel. diff. 4.8e2), so the slice is 8 x 8. tstat has none of these limits, and
also reconstructs confocal captures with pf (y-tal refuses them).

    python3 scripts/pf_vs_ytal.py [--tstat target/release/tstat] [--spp 64]
        [--out docs/results/pf_vs_ytal.md]

Not run by CI (needs y-tal 0.20). Exits non-zero when a check fails.
"""
import argparse, os, re, subprocess, sys, tempfile, time
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tstat", default=os.path.join(ROOT, "target/release/tstat"))
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs/results/pf_vs_ytal.md"))
    a = ap.parse_args()
    import tal
    from tal.enums import CameraSystem, VolumeFormat

    tmp = tempfile.mkdtemp(prefix="pf_vs_ytal_")
    bundle, h5 = os.path.join(tmp, "ex.tstats"), os.path.join(tmp, "ex.hdf5")
    run = lambda c: subprocess.run(c, check=True, capture_output=True, text=True)
    run([a.tstat, "render", os.path.join(ROOT, "scenes/nlos_T_exhaustive.xml"), "--out", bundle,
         "--spp", str(a.spp), "--start-opl", "0", "--bins", "1024"])
    run([a.tstat, "export", bundle, "--tal", h5])
    d = tal.io.read_capture(h5)
    cases = [("volume", [-1, -1, 0.5], [1, 1, 1.5], [41, 41, 21], 0.4),
             ("slice", [-0.875, -0.875, 1.0], [0.875, 0.875, 1.0], [8, 8, 1], 0.5)]
    rows, fail = [], False
    for name, lo, hi, n, wl in cases:
        xs = [np.linspace(lo[i], hi[i], n[i]) for i in range(3)]
        V = np.stack(np.meshgrid(*xs, indexing="ij"), -1)
        t0 = time.time()
        ref = np.abs(tal.reconstruct.pf_dev.solve(
            d, wl_mean=wl, wl_sigma=wl / np.sqrt(2), volume_xyz=V, volume_format=VolumeFormat.X_Y_Z_3,
            camera_system=CameraSystem.DIRECT_LIGHT, progress=False, nt=d.H.shape[0])).reshape(n)
        t_ytal = time.time() - t0
        times, solves, diffs = [], [], []
        for src in [bundle, h5]:
            out = os.path.join(tmp, f"{name}.npy")
            t0 = time.time()
            r = run([a.tstat, "nlos", "reconstruct", src, "--method", "pf", "--wl-mean", str(wl),
                 "--volume=" + ",".join(f"{lo[i]},{hi[i]}" for i in range(3)),
                 "--voxels", ",".join(map(str, n)), "--out", out, "--force"])
            times.append(time.time() - t0)
            solves.append(float(re.search(r" in ([0-9.]+) s", r.stdout + r.stderr).group(1)))
            mine = np.load(out)
            diffs.append(float(np.abs(mine - ref).max() / np.abs(ref).max()))
        peak = lambda v: tuple(int(k) for k in np.unravel_index(v.argmax(), v.shape))
        ok = max(diffs) <= 1e-3
        fail |= not ok
        rows.append(f"| {name} | {tuple(n)} | {wl} | {max(diffs):.1e} | {peak(ref)} / {peak(mine)} | "
                    f"{t_ytal:.2f} | {max(times):.2f} / {max(solves):.2f} | {t_ytal / max(times):.0f}x / "
                    f"{t_ytal / max(solves):.0f}x | {'pass' if ok else 'FAIL'} |")
    text = "\n".join([
        "# Phasor fields: tstat against y-tal", "",
        f"Command: `python3 scripts/pf_vs_ytal.py --spp {a.spp}` (y-tal {tal.__version__}); capture: "
        f"`scenes/nlos_T_exhaustive.xml` from OPL 0, 1024 bins, H {tuple(d.H.shape)}.", "",
        "| case | voxels | wl_mean | max rel. diff. | peak y-tal / tstat | y-tal s | tstat s: process / reconstruction | speed-up: process / reconstruction | check |",
        "|---|---|---|---|---|---|---|---|---|", *rows, "",
        "tstat's times: the whole process (reading the capture included) and the reconstruction alone (as it",
        "reports), the slower of the bundle and the HDF5 file; y-tal's is its solve (the capture already in",
        "memory), so the reconstruction columns compare like with like. The difference is relative to",
        "y-tal's maximum."]) + "\n"
    open(a.out, "w").write(text)
    print(text)
    sys.exit(1 if fail else 0)


if __name__ == "__main__":
    main()
