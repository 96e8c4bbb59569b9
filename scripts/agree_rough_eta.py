#!/usr/bin/env python3
"""Diagnostic: tstat against mitransient 1.3.1 with its NEE timing through rough
refraction corrected, on one scene (issue 48's test_homo_roughdielectric_spot_volpath).

mitransient's transient_prbvolpath times a light sample taken at a surface as
`distance + ds.dist * η`, with η the IOR product *before* the surface: when the light
lies across a rough refraction (wo and wi on opposite sides), the light segment is
timed with the IOR of the side the path came from. tstat times it with the IOR of the
light's side (tests/it/render_physics.rs::light_sampled_through_rough_glass_arrives_with_
the_air_segment_at_speed_c). This script patches that one line in a temporary copy
(η divided or multiplied by the surface's relative IOR ETA on a transmission; ETA is
given, the scene's one rough dielectric) and compares the transients with tstat's, as
published (`tstat render` with the default near-clip time origin).

    python3 scripts/agree_rough_eta.py SCENE.xml --eta 1.29964 [--spp 512] [-a DIR]

Prints both renderers' film-summed bins around the peak and the 95th percentile of the
relative difference of 16 x 16 px x 5 bin blocks (the suite's space-time column).
Measured (issue 48): the scene's copy at 32 px, 512 spp, near_clip 1: p95 0.081 with
the line corrected (mitransient's own seed spread 0.056 at 1024 spp), 0.975 without.
Not part of CI (needs mitransient; see scripts/agreement.py).
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

MIT = r"""
import os, sys, glob
libs = glob.glob('/usr/lib/x86_64-linux-gnu/libLLVM-19.so*') + glob.glob('/usr/lib/llvm-19/lib/libLLVM*.so*')
if libs: os.environ.setdefault('DRJIT_LIBLLVM_PATH', libs[0])
import mitsuba as mi
mi.set_variant('llvm_ad_rgb')
import mitransient, numpy as np, importlib.util, tempfile
import mitransient.integrators.transient_prbvolpath as tp
src = open(tp.__file__).read()
old = "add_transient(contrib, distance + ds.dist *\n                                      η, ray.wavelengths, active_e)"
assert src.count(old) == 1, "mitransient's source changed: no fix applied"
ETA = float(sys.argv[5])
new = ("add_transient(contrib, distance + ds.dist * dr.select(active_e_surface & (mi.Frame3f.cos_theta(si.wi) * "
       "mi.Frame3f.cos_theta(si.to_local(ds.d)) < 0), dr.select(mi.Frame3f.cos_theta(si.wi) < 0, η / %r, η * %r), η), "
       "ray.wavelengths, active_e)" % (ETA, ETA))
fn = os.path.join(tempfile.mkdtemp(), "transient_prbvolpath_eta_fix.py")
open(fn, "w").write(src.replace(old, new))
spec = importlib.util.spec_from_file_location(tp.__package__ + ".transient_prbvolpath_eta_fix", fn)
mod = importlib.util.module_from_spec(spec); sys.modules[spec.name] = mod; spec.loader.exec_module(mod)
for d in sys.argv[3].split(os.pathsep):
    if d: mi.file_resolver().append(d)
scene = mi.load_file(sys.argv[1])
steady, transient = scene.integrator().render(scene, spp=int(sys.argv[2]), seed=1)
np.save(sys.argv[4], np.array(transient)[..., :3])
"""


def blocks(a, bt=5):
    h, w, t = a.shape
    return a[:h // 16 * 16, :w // 16 * 16, :t // bt * bt].reshape(
        h // 16, 16, w // 16, 16, t // bt, bt).sum((1, 3, 5))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--eta", type=float, required=True)
    ap.add_argument("--spp", type=int, default=512)
    ap.add_argument("-a", dest="search", action="append", default=[])
    ap.add_argument("--tstat", default=os.path.join(ROOT, "target", "release", "tstat"))
    a = ap.parse_args()
    tmp = tempfile.mkdtemp()
    mit = os.path.join(tmp, "mit.npy")
    subprocess.run([sys.executable, "-c", MIT, a.scene, str(a.spp), os.pathsep.join(a.search), mit,
                    str(a.eta)], check=True)
    b = os.path.join(tmp, "t.tstats")
    extra = sum((["-a", d] for d in a.search), [])
    subprocess.run([a.tstat, "render", a.scene, "--out", b, "--spp", str(a.spp), *extra],
                   check=True, capture_output=True)
    subprocess.run([a.tstat, "export", b, "--out", os.path.join(tmp, "t.npy")], check=True,
                   capture_output=True)
    m = np.load(mit).sum(-1)
    t = np.load(os.path.join(tmp, "t.npy")).sum(-1)
    mm, tt = m.sum((0, 1)), t.sum((0, 1))
    k = int(np.argmax(mm))
    r = slice(max(0, k - 4), k + 6)
    np.set_printoptions(precision=3, suppress=True, linewidth=200)
    print(f"bins {r.start}..{r.stop - 1}\nmitransient (fixed) {mm[r]}\ntstat               {tt[r]}")
    bm, bt = blocks(m), blocks(t)
    keep = bm > bm.max() * 1e-2
    print(f"space-time p95 {np.percentile(np.abs(bt[keep] - bm[keep]) / bm[keep], 95):.3f}, "
          f"energy tstat {t.sum():.4f} mitransient {m.sum():.4f}")


if __name__ == "__main__":
    main()
