#!/usr/bin/env python3
"""tstat against mitransient on public scene files, image by image.

For each scene: a copy with a smaller film (WIDTH px wide, the height keeping the
aspect ratio, the published time bins) is written to a temporary folder with a
`<path>` back to the scene's folder, so both renderers read the same meshes and
textures. mitransient renders it at two seeds (its own seed-to-seed spread is the
yardstick), tstat at one (`tstat render`, its bundle's steady image and X1 / spp).
Printed, one Markdown row per scene:

- steady mean ratio per channel (tstat / mitransient seed 1);
- steady 8x8-pixel blocks: largest relative difference of tstat and of mitransient's
  second seed against the first (blocks whose mean is above 1% of the brightest);
- space-time blocks (16 x 16 px x 5 bins): 95th percentile of the relative difference,
  same two columns;
- the copy changes nothing but the film size (and the spp): both renderers time
  camera rays from the near-clip plane (tstat's default time origin), so a scene's
  near_clip shows up in neither column, as its author rendered it;
- the share of the steady image's energy that mitransient's transient holds (it drops
  what it cannot time, e.g. escapes to infinitely distant emitters) and tstat's.

    python3 scripts/agree_wild.py SCENE.xml... [--spp 1024] [--width 64] [--tstat BIN]

Not part of CI (needs mitransient: see scripts/compare_mitransient.py for set-up).
"""
import argparse
import glob
import json
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

PARAMETERS = {"spp": "4", "max_depth": "8", "rr_depth": "5", "integrator": "transient_path"}

MIT = r"""
import os, sys, glob
libs = glob.glob('/usr/lib/x86_64-linux-gnu/libLLVM-19.so*') + glob.glob('/usr/lib/llvm-19/lib/libLLVM*.so*')
if libs: os.environ.setdefault('DRJIT_LIBLLVM_PATH', libs[0])
import mitsuba as mi
mi.set_variant('llvm_ad_rgb')
import mitransient, numpy as np, json
if os.environ.get('TSTAT_MIT_NEE_FIX'):
    # Diagnostic only (docs/results/agreement_media.md): mitransient 1.3.1's
    # transient_prbvolpath restarts a shadow ray past a null surface with Mitsuba's
    # offset (si.spawn_ray) but keeps the remaining distance measured from the surface,
    # so the ray ends past the light sample, on the emitter's own surface, and is
    # blocked. Run with the restart moved 2e-5 along the ray instead: the source is
    # patched in a temporary copy (dr.syntax re-reads it from its file).
    import importlib.util, tempfile
    import mitransient.integrators.transient_prbvolpath as tp
    src = open(tp.__file__).read()
    old = "ray[active_surface] = dr.detach(si.spawn_ray(mi.Vector3f(ray.d)))"
    assert src.count(old) == 1, "mitransient's source changed: no NEE fix applied"
    src = src.replace(old, "ray[active_surface] = dr.detach(mi.Ray3f(si.p + 2e-5 * ray.d, "
                           "mi.Vector3f(ray.d), ray.time, ray.wavelengths))")
    fn = os.path.join(tempfile.mkdtemp(), "transient_prbvolpath_nee_fix.py")
    open(fn, "w").write(src)
    spec = importlib.util.spec_from_file_location(tp.__package__ + ".transient_prbvolpath_nee_fix", fn)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
kw = json.loads(sys.argv[4])
for folder in json.loads(sys.argv[6]):
    mi.Thread.thread().file_resolver().append(folder)
scene = mi.load_file(sys.argv[1], **kw)
steady, transient = scene.integrator().render(scene, spp=int(sys.argv[2]), seed=int(sys.argv[3]))
np.save(sys.argv[5] + '_steady.npy', np.array(steady))
np.save(sys.argv[5] + '_transient.npy', np.array(transient))
"""


def defaults_of(text):
    return dict(re.findall(r'<default\s+name="([^"]+)"\s+value="([^"]*)"', text))


def small_copy(path, width, out_dir):
    """The scene with its film shrunk; None when the film is not in this file."""
    text = open(path, encoding="utf-8").read()
    defaults = defaults_of(text)
    root = ET.fromstring(text)
    film = root.find("./sensor/film")
    if film is None:
        return None, None
    vals = {}
    for e in film:
        if e.get("name") in ("width", "height"):
            v = e.get("value")
            if v.startswith("$"):
                v = defaults.get(v[1:], "256")
            vals[e.get("name")] = int(v)
    w, h = vals.get("width", 768), vals.get("height", 576)
    nh = max(1, round(width * h / w))
    for e in film:
        if e.get("name") == "width":
            e.set("value", str(width))
        if e.get("name") == "height":
            e.set("value", str(nh))
    if "width" not in vals:
        ET.SubElement(film, "integer", name="width", value=str(width))
    if "height" not in vals:
        ET.SubElement(film, "integer", name="height", value=str(nh))
    p = ET.Element("path", value=os.path.dirname(os.path.abspath(path)))
    root.insert(0, p)
    out = os.path.join(out_dir, os.path.basename(path))
    ET.ElementTree(root).write(out)
    needed = {k: v for k, v in PARAMETERS.items() if f"${k}" in text and k not in defaults}
    return out, needed


def blocks(a, by, bx, bt=None):
    h, w = a.shape[0] // by * by, a.shape[1] // bx * bx
    a = a[:h, :w]
    if bt is None:
        return a.reshape(h // by, by, w // bx, bx, -1).mean((1, 3))
    t = a.shape[2] // bt * bt
    a = a[:, :, :t]
    return a.reshape(h // by, by, w // bx, bx, t // bt, bt, -1).sum((1, 3, 5))


def rel(a, b, floor):
    m = b > floor
    return np.abs(a[m] - b[m]) / b[m] if m.any() else np.array([0.0])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("-a", dest="search", action="append", default=[],
                    help="a folder to search for the scene's files (Mitsuba's -a; repeatable); "
                         "mitsuba-data scenes get its common/ folder without asking")
    ap.add_argument("--keep", help="a folder to keep each scene's renders in (NAME/)")
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--tstat", default=os.path.join(here, "..", "target", "release", "tstat"))
    a = ap.parse_args()
    print("| scene | steady mean ratio (R, G, B) | 8x8 block max: tstat / mit seed 2 | "
          "space-time p95: tstat / mit seed 2 | transient energy / steady: tstat / mit |")
    print("|---|---|---|---|---|")
    for s in a.scenes:
        name = os.path.relpath(s, os.path.join(here, "..", "..", "shared", "wild-scenes"))
        with tempfile.TemporaryDirectory() as d:
            copy, needed = small_copy(s, a.width, d)
            if copy is None:
                print(f"| {name} | film in an included file: skipped | | | |")
                continue
            if a.keep:
                d = os.path.join(a.keep, os.path.basename(s)[:-4])
                os.makedirs(d, exist_ok=True)
                copy, needed = small_copy(s, a.width, d)
            search = list(a.search)
            m = re.search(r"^(.*mitsuba-renderer_mitsuba-data)" + re.escape(os.sep), os.path.abspath(s))
            if m and os.path.isdir(os.path.join(m.group(1), "common")):
                search.append(os.path.join(m.group(1), "common"))
            ms = []
            for seed in (1, 2):
                r = subprocess.run([sys.executable, "-c", MIT, copy, str(a.spp), str(seed),
                                    json.dumps(needed), os.path.join(d, f"m{seed}"), json.dumps(search)],
                                   capture_output=True, text=True)
                if r.returncode:
                    print(f"| {name} | mitransient failed: {r.stderr.strip().splitlines()[-1][:120]} | | | |")
                    break
                ms.append((np.load(os.path.join(d, f"m{seed}_steady.npy")),
                           np.load(os.path.join(d, f"m{seed}_transient.npy"))))
            if len(ms) < 2:
                continue
            cmd = [a.tstat, "render", copy, "--spp", str(a.spp), "--seed", "1",
                   "--out", os.path.join(d, "t.tstats"), "--force"]
            for k, v in needed.items():
                cmd += ["-D", f"{k}={v}"]
            for folder in search:
                cmd += ["-a", folder]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode:
                print(f"| {name} | tstat failed: {r.stderr.strip().splitlines()[-1][:120]} | | | |")
                continue
            b = os.path.join(d, "t.tstats")
            spp = json.load(open(os.path.join(b, "manifest.json")))["spp"]
            ts, tt = np.load(os.path.join(b, "steady.npy")), np.load(os.path.join(b, "x1.npy")) / spp
            (m1s, m1t), (m2s, m2t) = ms
            m1s, m2s = m1s[..., :3], m2s[..., :3]
            m1t, m2t = m1t[..., :3], m2t[..., :3]
            ratio = ts.mean((0, 1)) / np.maximum(m1s.mean((0, 1)), 1e-12)
            sb, mb1, mb2 = (blocks(x, 8, 8) for x in (ts, m1s, m2s))
            fl = mb1.max() * 0.01
            st, mt1, mt2 = (blocks(x, 16, 16, 5) for x in (tt, m1t, m2t))
            ft = mt1.max() * 0.01
            e_t = tt.sum() / max(ts.sum(), 1e-12)
            e_m = m1t.sum() / max(m1s.sum(), 1e-12)
            print(f"| {name} | {ratio[0]:.4f} / {ratio[1]:.4f} / {ratio[2]:.4f} | "
                  f"{rel(sb, mb1, fl).max():.3f} / {rel(mb2, mb1, fl).max():.3f} | "
                  f"{np.percentile(rel(st, mt1, ft), 95):.3f} / {np.percentile(rel(mt2, mt1, ft), 95):.3f} | "
                  f"{e_t:.3f} / {e_m:.3f} |", flush=True)


if __name__ == "__main__":
    main()
