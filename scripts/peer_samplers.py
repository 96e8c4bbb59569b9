#!/usr/bin/env python3
"""Time to a given error: tstat's pipelines against mitransient under each of Mitsuba's
samplers, on one scene, against one reference bundle.

    python3 scripts/peer_samplers.py SCENE.xml REFERENCE.tstats \
        [--spp 16,64,256] [--seeds 2] [--film 64,150,0.08] [--out docs/results/peer_X.md]

- mitransient 1.3.1 (Mitsuba 3.9.1, llvm_ad_rgb, 2 threads) renders a copy of SCENE
  whose `<sampler>` is each of independent, stratified, multijitter, ldsampler and
  orthogonal, at every spp and seed. One process per sampler: an untimed warm-up
  render at each spp first (Dr.Jit compiles a kernel per spp; a cold compile added
  about 0.15 s to the first timed render of each spp before 2026-12-07, so the speed-ups
  published before then flatter tstat), then each render is timed from
  `integrator.render` until its images are evaluated.
- tstat renders the same scene file in each of `--modes`: `sobol`, `stratified`,
  `adaptive` (`--sampler sobol --adaptive`, minimising the all-voxel MSE) and
  `adaptive_rel` (the same minimising relMSE), each noisy (`tstat export`) and denoised
  (`tstat denoise`, its default method); its time is the manifest's render_seconds (plus
  the pilot's seconds for adaptive renders) plus the denoiser's own seconds (reading the
  bundle and writing the volume included).
- Errors: RMSE over all voxels, the pixels that see the light (the reference's emitter
  G-buffer > 0) and the rest, against the reference's mean, with the reference's own
  variance of the mean (from its X1, X2: use an independent-sampling reference)
  subtracted from each squared error.
- Equal-error speed-up of a tstat pipeline over a mitransient sampler at spp s: the time
  mitransient took at s over the time tstat needs for mitransient's error there,
  interpolated log-log along tstat's spp curve (">" / "<" when outside tstat's
  range: the bound is then its nearest end).
- The same at tstat's own mean spp (tables "at its mean spp"): mitransient's time to the
  error tstat's adaptive pipeline reaches at each `--spp`, over tstat's time, interpolated
  along mitransient's curve; `--mi-spp 1024,4096` adds the higher counts that needs.
- `--mi-reference N`: mitransient's errors against its own answer (the mean of two
  ldsampler renders of N spp, their variance subtracted), for scenes where the two
  renderers converge apart (an explained difference in docs/agreement.md).
- `TSTAT=/path/to/tstat` runs another binary than target/release/tstat.

Not part of CI (needs mitransient: `pip install mitransient==1.3.1`, and libLLVM,
`apt-get install -y libllvm19`; see scripts/compare_mitransient.py).
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sampler_error import load_reference  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TSTAT = os.environ.get("TSTAT", os.path.join(ROOT, "target", "release", "tstat"))
MI_SAMPLERS = ["independent", "stratified", "multijitter", "ldsampler", "orthogonal"]
MARK = "peer_samplers result: "

WORKER = r"""
import os, sys, glob, json, time
libs = glob.glob('/usr/lib/x86_64-linux-gnu/libLLVM-19.so*') + glob.glob('/usr/lib/llvm-19/lib/libLLVM*.so*')
if libs: os.environ.setdefault('DRJIT_LIBLLVM_PATH', libs[0])
import drjit as dr, mitsuba as mi
mi.set_variant('llvm_ad_rgb')
import mitransient, numpy as np
dr.set_thread_count(2)
scene_file, params, jobs, out = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3]), sys.argv[4]
scene = mi.load_file(scene_file, **params)
# One untimed render per spp first: Dr.Jit compiles a kernel per spp (the spp is a
# literal in it), ~0.15 s here, unless its on-disk cache holds it already.
for spp in sorted({spp for spp, _ in jobs}):
    s, t = scene.integrator().render(scene, spp=spp, seed=999)
    dr.eval(s, t); dr.sync_thread()
for spp, seed in jobs:
    t0 = time.perf_counter()
    s, t = scene.integrator().render(scene, spp=spp, seed=seed)
    dr.eval(s, t); dr.sync_thread()
    dt = time.perf_counter() - t0
    np.save(f"{out}_{spp}_{seed}.npy", np.array(t)[..., :3])
    print("MARK" + json.dumps({"spp": spp, "seed": seed, "seconds": dt}), flush=True)
""".replace("MARK", MARK)


def errors(vol, ref, ref_var, light):
    d = (vol.astype(np.float64) - ref) ** 2 - ref_var
    # relmse: the report's relative MSE, (x - ref)^2 / (ref^2 + 0.01) (its "RMSE" column
    # below is the square root of that mean).
    return {"all": d.mean(), "light": d[light].mean(), "rest": d[~light].mean(),
            "relmse": (d / (ref ** 2 + 1e-2)).mean()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("reference")
    ap.add_argument("--spp", default="16,64,256")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--film", default="64,150,0.08")
    ap.add_argument("--tstat-extra", default="4,8",
                    help="extra (lower) spp for tstat's curves, so that equal errors are interpolated")
    ap.add_argument("--modes", default="sobol,stratified",
                    help="tstat pipelines: sobol, stratified, adaptive (sobol with --adaptive), "
                         "adaptive_rel (the same minimising relMSE)")
    ap.add_argument("--mi-samplers", default=",".join(MI_SAMPLERS),
                    help="mitransient samplers to time (default: all five)")
    ap.add_argument("--mi-spp", default="",
                    help="mitransient's spp (default: --spp); add higher counts (e.g. 1024,4096) so "
                         "that its time to tstat's errors is interpolated, not bounded")
    ap.add_argument("--mi-reference", type=int, default=0,
                    help="measure mitransient against its own answer: two ldsampler renders of "
                         "this many spp (seeds 1001, 1002), their mean, its variance from their "
                         "difference subtracted (for scenes where the two renderers converge apart)")
    ap.add_argument("--out")
    a = ap.parse_args()
    spps = [int(s) for s in a.spp.split(",")]
    mi_spps = sorted(set(spps) | {int(s) for s in a.mi_spp.split(",") if s})
    res, bins, width = a.film.split(",")
    params = {"res": res, "temporal_bins": bins, "bin_width_opl": width}
    tmp = tempfile.mkdtemp()

    ref, light, ref_var = load_reference(a.reference, tmp)
    n = json.load(open(os.path.join(a.reference, "manifest.json")))["spp"]

    # curves[name][spp] = (seconds, {region: mse}) averaged over seeds
    curves = {}

    def add(name, spp, secs, err):
        c = curves.setdefault(name, {}).setdefault(spp, [[], {"all": [], "light": [], "rest": [], "relmse": []}])
        c[0].append(secs)
        for k, v in err.items():
            c[1][k].append(v)

    text = open(a.scene, encoding="utf-8").read()
    mi_samplers = [x for x in a.mi_samplers.split(",") if x]
    def mi_render(sampler, jobs):
        """Renders `jobs` ((spp, seed) pairs) with mitransient under `sampler` in one
        process; returns [(volume, {spp, seed, seconds})] in order, or None when it failed."""
        copy = os.path.join(tmp, f"mi_{sampler}.xml")
        t2 = re.sub(r'<sampler type="[a-z_]+"', f'<sampler type="{sampler}"', text)
        t2 = t2.replace("<scene version=\"3.0.0\">",
                        f"<scene version=\"3.0.0\"><path value=\"{os.path.dirname(os.path.abspath(a.scene))}\"/>", 1)
        open(copy, "w").write(t2)
        out = os.path.join(tmp, f"mi_{sampler}")
        r = subprocess.run([sys.executable, "-c", WORKER, copy, json.dumps(params), json.dumps(jobs), out],
                           capture_output=True, text=True)
        results = [json.loads(l.split(MARK, 1)[1]) for l in r.stdout.splitlines() if MARK in l]
        if r.returncode != 0 or len(results) != len(jobs):
            print(f"mitransient {sampler} failed: {(r.stderr.strip().splitlines() or ['?'])[-1]}", file=sys.stderr)
            return None
        return [(np.load(f"{out}_{x['spp']}_{x['seed']}.npy"), x) for x in results]

    # mitransient's errors are against `mi_ref` (the tstat reference unless --mi-reference).
    mi_ref, mi_ref_var = ref, ref_var
    if a.mi_reference:
        jobs = [(a.mi_reference, 1001), (a.mi_reference, 1002)]
        vols = mi_render("ldsampler", jobs)
        if vols is None:
            sys.exit("mitransient's reference render failed")
        r1, r2 = (v.astype(np.float64) for v, _ in vols)
        mi_ref = (r1 + r2) / 2
        # E (r1 - r2)^2 = 2 s^2 per voxel; the mean's variance is s^2 / 2.
        mi_ref_var = (r1 - r2) ** 2 / 4
    for sampler in mi_samplers:
        jobs = [(s, seed) for s in mi_spps for seed in range(1, a.seeds + 1)]
        vols = mi_render(sampler, jobs)
        if vols is None:
            continue
        for vol, res_ in vols:
            add(f"mitransient {sampler}", res_["spp"], res_["seconds"], errors(vol, mi_ref, mi_ref_var, light))
        print(f"mitransient {sampler}: done", file=sys.stderr)

    film = ["-D", f"res={res}", "-D", f"temporal_bins={bins}", "-D", f"bin_width_opl={width}"]
    tstat_spps = sorted(set(spps) | {int(x) for x in a.tstat_extra.split(",") if x})
    for mode in a.modes.split(","):
        # adaptive: allocation for the all-voxel MSE (the default); adaptive_rel: for relMSE.
        flags = {"adaptive": ["--sampler", "sobol", "--adaptive"],
                 "adaptive_rel": ["--sampler", "sobol", "--adaptive", "--adaptive-measure", "relmse"]
                 }.get(mode, ["--sampler", mode])
        for spp in tstat_spps:
            for seed in range(1, a.seeds + 1):
                b = os.path.join(tmp, "t.tstats")
                subprocess.run([TSTAT, "render", a.scene, "--out", b, "-D", f"spp={spp}", *film,
                                *flags, "--seed", str(seed), "--force"],
                               check=True, capture_output=True)
                man = json.load(open(os.path.join(b, "manifest.json")))
                # Adaptive renders: the pilot's time counts too.
                rs = man["render_seconds"] + man.get("adaptive", {}).get("pilot_seconds", 0.0)
                out = os.path.join(tmp, "t.npy")
                subprocess.run([TSTAT, "export", b, "--out", out, "--force"], check=True, capture_output=True)
                add(f"tstat {mode} noisy", spp, rs, errors(np.load(out), ref, ref_var, light))
                r = subprocess.run([TSTAT, "denoise", b, "--out", out, "--force"],
                                   check=True, capture_output=True, text=True)
                said = re.search(r"denoised .* in ([0-9.]+) s", r.stdout + r.stderr)
                ds = float(said.group(1))
                add(f"tstat {mode} denoised", spp, rs + ds, errors(np.load(out), ref, ref_var, light))
        print(f"tstat {mode}: done", file=sys.stderr)

    def point(name, spp, region):
        secs, err = curves[name][spp]
        return float(np.mean(secs)), float(np.sqrt(max(np.mean(err[region]), 0)))

    lines = [f"# Time to error: tstat against mitransient's samplers, {os.path.basename(a.scene)}", "",
             f"Film {res}x{res}, {bins} bins of {width} OPL; {a.seeds} seeds per point; reference "
             f"`{os.path.basename(a.reference)}` ({n} spp, its variance subtracted). Generated by",
             f"`python3 scripts/peer_samplers.py {os.path.basename(a.scene)} REF --spp {a.spp} --seeds {a.seeds} --film {a.film} --modes {a.modes}"
             + (f" --mi-spp {a.mi_spp}" if a.mi_spp else "")
             + (f" --mi-reference {a.mi_reference}" if a.mi_reference else "") + "`."
             + (" mitransient's errors are against its own answer: the mean of two ldsampler renders of "
                f"{a.mi_reference} spp, their variance subtracted." if a.mi_reference else ""),
             "", "## RMSE and time", "", "| pipeline | spp | seconds | RMSE all | light | rest | relMSE |", "|---|---|---|---|---|---|---|"]
    for name in curves:
        for spp in sorted(curves[name]):
            if True:
                t = point(name, spp, "all")[0]
                e = [point(name, spp, r)[1] for r in ("all", "light", "rest", "relmse")]
                lines.append(f"| {name} | {spp} | {t:.3f} | {e[0]:.3e} | {e[1]:.3e} | {e[2]:.3e} | {e[3] ** 2:.3e} |")

    def time_to(name, e, region):
        """When `name`'s error reaches e, interpolated log-log along its spp curve:
        (seconds, ""), or beyond the curve its nearest end with "<" (its cheapest point
        is already as accurate: at most that long) or ">" (its most accurate point is
        not: longer than that)."""
        pts = sorted((point(name, s, region) for s in curves[name]), key=lambda p: p[0])
        lt = np.log([p[0] for p in pts])
        le = np.log([max(p[1], 1e-30) for p in pts])
        target = np.log(max(e, 1e-30))
        # Along a curve error falls with time: find where it crosses the target.
        for i in range(len(pts) - 1):
            if (le[i] - target) * (le[i + 1] - target) <= 0 and le[i] != le[i + 1]:
                f = (target - le[i]) / (le[i + 1] - le[i])
                return float(np.exp(lt[i] + f * (lt[i + 1] - lt[i]))), ""
        if target > le[0]:
            return pts[0][0], "<"
        return pts[-1][0], ">"

    def speedup(tst, mi_name, spp, region):
        """mitransient's time at `spp` over tstat's time to mitransient's error there."""
        t_mi, e_mi = point(mi_name, spp, region)
        t, bound = time_to(tst, e_mi, region)
        return f"{ {'<': '>', '>': '<', '': ''}[bound]}{t_mi / t:.2f}x"

    def speedup_at(tst, spp, mi_name, region):
        """mitransient's time to the error tstat's pipeline reaches at its own `spp`, over
        tstat's time there."""
        t_t, e_t = point(tst, spp, region)
        t, bound = time_to(mi_name, e_t, region)
        return f"{bound}{t / t_t:.2f}x"

    for tst in ["tstat adaptive denoised", "tstat adaptive_rel denoised"]:
        if tst not in curves:
            continue
        have = [s for s in ("ldsampler", "multijitter") if f"mitransient {s}" in curves]
        if not have:
            continue
        lines += ["", f"## Equal-error speed-up of {tst} at its mean spp (above 1: tstat is faster)", "",
                  "tstat's pipeline at its mean spp reaches an error in a time; the cell is the time "
                  "mitransient needs for that error (interpolated along its spp curve "
                  f"{', '.join(str(x) for x in mi_spps)}) over tstat's time.", "",
                  "| spp (tstat, mean) | region | " + " | ".join(have) + " | best |",
                  "|---|---|" + "---|" * (len(have) + 1)]
        for spp in spps:
            if spp not in curves[tst]:
                continue
            for region in ("all", "light", "rest", "relmse"):
                cells = [speedup_at(tst, spp, f"mitransient {s}", region) for s in have]
                best = min(zip([float(c.strip("<>x")) for c in cells], cells, have))
                lines.append(f"| {spp} | {region} | " + " | ".join(cells) + f" | {best[1]} ({best[2]}) |")

    for tst in ["tstat adaptive denoised", "tstat adaptive_rel denoised", "tstat adaptive noisy",
                "tstat sobol denoised", "tstat sobol noisy", "tstat stratified denoised"]:
        if tst not in curves:
            continue
        # "best": the lower of the speed-ups over ldsampler and multijitter (mitransient at
        # its best sampler for time to error; orthogonal is more accurate per sample but
        # slower per sample).
        lines += ["", f"## Equal-error speed-up of {tst} (above 1: tstat is faster)", "",
                  "| spp (mitransient) | region | " + " | ".join(s for s in mi_samplers) + " | best |",
                  "|---|---|" + "---|" * (len(mi_samplers) + 1)]
        for spp in spps:
            for region in ("all", "light", "rest", "relmse"):
                have = [s for s in mi_samplers if f"mitransient {s}" in curves and spp in curves[f"mitransient {s}"]]
                cells = [speedup(tst, f"mitransient {s}", spp, region) if s in have else "-" for s in mi_samplers]
                pair = [(float(speedup(tst, f"mitransient {s}", spp, region).strip("<>x")),
                         speedup(tst, f"mitransient {s}", spp, region), s)
                        for s in ("ldsampler", "multijitter") if s in have]
                cells.append(f"{min(pair)[1]} ({min(pair)[2]})" if pair else "-")
                lines.append(f"| {spp} | {region} | " + " | ".join(cells) + " |")
    report = "\n".join(lines) + "\n"
    print(report)
    if a.out:
        open(a.out, "w").write(report)


if __name__ == "__main__":
    main()
