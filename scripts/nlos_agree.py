#!/usr/bin/env python3
"""Agreement study: tstat's NLOS captures against mitransient 1.3.1 (transient_nlos_path +
nlos_capture_meter), on the same scene files, with mitransient at two seeds as the
yardstick for Monte Carlo noise.

BIN (--tstat) defaults to target/release/tstat.

usage: python3 scripts/nlos_agree.py [--spp N] [--tstat BIN] [--only KEY[,KEY..]]
                                     [--work DIR] [--keep] [--json OUT.json]
       python3 scripts/nlos_agree.py --probe [--tstat BIN]
       python3 scripts/nlos_agree.py --onset [--tstat BIN]

Results and conclusions: docs/results/nlos_agreement.md.

For every case below, renders
  * tstat  (`BIN render ... --pixel-sampling independent`) at seeds 1 and 2,
  * mitransient (scripts/nlos_mitransient.py) at seeds 1 (timed after a --warmup) and 2,
all at the same spp (the case's default, or --spp N for every case), converts tstat's
bundle mean x1/spp into mitransient's native layout (exhaustive: tstat row (ly*Lw+lx)*Sy+sy
-> mit[sy, sx, ly, lx]) and prints a Markdown table:

  E t/m1, E m2/m1  total energy ratios (sum over everything)
  zE               (E_t1 - E_m1) / sqrt(var_t + var_m); each variance is estimated from
                   the two seeds per independent sensor pixel, var = 1/2 sum_p (a_p - b_p)^2
                   (many degrees of freedom, so a stable yardstick, unlike |m2/m1 - 1|)
  bins t-m1, m2-m1 max over time bins holding > 1% of m1's peak bin of |a - b| / b of the
                   per-bin energy (sum over pixels, laser points and channels)
  blk95 t-m1, m2-m1 95th percentile over space-time blocks above 1% of m1's brightest
                   block of |a - b| / b (block sizes per case, listed in the second table)
  nz bins          first-last non-zero bin of t1 / m1 / m2
  arrival          energy-weighted mean OPL per pixel (sensor pixel, or (sensor, laser)
                   pair), t1 - m1 and m2 - m1, averaged over pixels weighted by m1's energy,
                   in bins, +- its standard error from the two seeds (a time shift shows
                   here); m2 - m1 for comparison
  dark px          units (pixels, or (sensor, laser) pairs) zero in both seeds of tstat
                   and above 10% of m1's median lit unit in both of mitransient's (and
                   the reverse)
  times            tstat: manifest render_seconds (seed 1) and process wall;
                   mitransient: render wall time after a warm-up render (seed 1)
  peak RSS         /usr/bin/time's maximum resident set size of the seed-1 processes
                   (mitransient's includes Python, Dr.Jit's LLVM JIT and the warm-up render)
  verdict          "agrees" when |zE| <= 3, bins <= 1.5x and blk95 <= 1.5x mitransient's own
                   seed spread, t1's first non-zero bin lies within 2 bins of m1/m2's, and
                   there are no dark pixels; otherwise the failing criteria are listed.

Inputs, all inside the repository or its sibling ../shared: scenes/nlos_T.xml and
scenes/nlos_T_exhaustive.xml; scripts/nlos_peer_scenes/nlos_Z_{confocal,exhaustive}.xml
(the public nlos_Z.xml rewritten for mitransient 1.3.1, Z.obj found relative to their
folder); ../shared/wild-scenes/diegoroyo_mitransient/examples/transient-nlos/.
Scene variants are written to --work (default <tmpdir>/nlos_agree_work): nlos_T.xml as
single / NEE (wide projector) / no-HGS / afalb captures, with the T at z = 2 and with the
relay wall moved off the origin, nlos-z-simple.xml with absolute mesh paths and a 32x32 film. The legacy
examples/transient-nlos/nlos_Z.xml is given unchanged to both (tstat converts the legacy
meter parameters itself; nlos_mitransient.py --legacy convert does the same for
mitransient). Bin starts are chosen so that no echo begins exactly on a bin edge (the T
at z = 1 echoes from OPL 2.0, bins start at 1.902; at z = 2 from 4.0, start 3.902):
mitransient's echoes arrive slightly early (see --onset), which moves mass across an
edge that an echo starts on.

--probe is the regression check for the laser-sampling shadow-ray bug this study found
(fixed in 11e593d): before the fix tstat's laser sampling dropped every lit point seen
more than asin(sqrt(h / (1 + max abs coord))) from the hidden vertex's normal, h = its
height above the wall (its shadow ray, moved off the surface but still parallel to the
unmoved direction, met the wall short of the lit point). A tiny hidden patch, bisection
of the angle beyond which tstat's transient is exactly zero; it must read "none below
80" for every row (exit status 1 otherwise).

--onset measures the time offset between the two renderers: a 4 mm patch at distance cz
from a 1 mm relay wall, 10 um bins around OPL 2 cz; prints each renderer's energy-weighted
mean arrival minus 2 cz and the energy fraction arriving before 2 cz, for walls centred
at x = wx = 0, 1, 3 (Mitsuba's ray offset grows with the coordinates).
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
MITR = ROOT / 'scripts' / 'nlos_mitransient.py'
NLOS_T = ROOT / 'scenes' / 'nlos_T.xml'
NLOS_T_EXH = ROOT / 'scenes' / 'nlos_T_exhaustive.xml'
PEER = ROOT / 'scripts' / 'nlos_peer_scenes'
EX = ROOT.parent / 'shared' / 'wild-scenes' / 'diegoroyo_mitransient' / 'examples' / 'transient-nlos'
TIME = Path('/usr/bin/time')   # for peak RSS; skipped when absent


# ---------------------------------------------------------------- scene variants
def sub1(text, old, new):
    assert text.count(old) == 1, (old, text.count(old))
    return text.replace(old, new)


def t_variant(work, name, capture=None, exhaustive=False, laser_sampling=None, hgs=None,
              afalb=None, fov=None, start_opl=None, bin_width=None, tz=None, wall_x=None):
    x = NLOS_T.read_text()
    if wall_x is not None:   # move the relay wall (only) along x
        x = sub1(x, '<shape type="rectangle" id="relay_wall">\n',
                 '<shape type="rectangle" id="relay_wall">\n        <transform name="to_world">'
                 f'<translate x="{wall_x}" y="0" z="0"/></transform>\n')
    if tz is not None:   # move the hidden T away from the wall (z = 1 in nlos_T.xml)
        x = sub1(x, '<translate x="0" y="0.32" z="1"/>', f'<translate x="0" y="0.32" z="{tz}"/>')
        x = sub1(x, '<translate x="0" y="-0.16" z="1"/>',
                 f'<translate x="0" y="-0.16" z="{tz}"/>')
    if capture:
        x = sub1(x, '<string name="capture_type" value="confocal"/>',
                 f'<string name="capture_type" value="{capture}"/>')
    if exhaustive:
        x = sub1(x, '<rfilter type="box"/>',
                 '<boolean name="exhaustive_scan" value="true"/>\n'
                 '                <integer name="laser_scan_width" value="$res"/>\n'
                 '                <integer name="laser_scan_height" value="$res"/>\n'
                 '                <rfilter type="box"/>')
    if laser_sampling is not None:
        x = sub1(x, '<boolean name="nlos_laser_sampling" value="true"/>',
                 f'<boolean name="nlos_laser_sampling" value="{str(laser_sampling).lower()}"/>')
    if hgs is not None:
        x = sub1(x, '<boolean name="nlos_hidden_geometry_sampling" value="true"/>',
                 f'<boolean name="nlos_hidden_geometry_sampling" value="{str(hgs).lower()}"/>')
    if afalb is not None:
        x = sub1(x, '<boolean name="account_first_and_last_bounces" value="false"/>',
                 f'<boolean name="account_first_and_last_bounces" value="{str(afalb).lower()}"/>')
    if fov is not None:
        x = sub1(x, '<float name="fov" value="0.2"/>', f'<float name="fov" value="{fov}"/>')
    if start_opl is not None:
        x = sub1(x, '<float name="start_opl" value="1.902"/>',
                 f'<float name="start_opl" value="{start_opl}"/>')
    if bin_width is not None:
        x = sub1(x, '<float name="bin_width_opl" value="0.004"/>',
                 f'<float name="bin_width_opl" value="{bin_width}"/>')
    p = work / f'{name}.xml'
    p.write_text(x)
    return p


def z_simple(work):
    x = (EX / 'nlos-z-simple.xml').read_text()
    x = sub1(x, '<integer name="width" value="32"/>', '<integer name="width" value="$w"/>')
    x = sub1(x, '<integer name="height" value="32"/>', '<integer name="height" value="$h"/>')
    x = re.sub(r'value="(meshes/[^"]+)"', lambda m: f'value="{EX / m.group(1)}"', x)
    x = sub1(x, '<scene version="2.1.0">',
             '<scene version="2.1.0">\n\t<default name="w" value="32"/>\n'
             '\t<default name="h" value="32"/>')
    p = work / 'nlos-z-simple_abs.xml'
    p.write_text(x)
    return p


# Each case: key, label, scene builder, -D defines (both renderers), default spp,
# block sizes (one per non-time axis of mitransient's layout, then time).
CASES = [
    dict(key='T_confocal', label='nlos_T confocal 16x16, 512 bins',
         scene=lambda w: NLOS_T, defines=dict(res=16, bins=512), spp=256,
         block=(4, 4, 16)),
    dict(key='T_single', label='nlos_T single 16x16, 512 bins',
         scene=lambda w: t_variant(w, 'T_single', capture='single'),
         defines=dict(res=16, bins=512), spp=256, block=(4, 4, 16)),
    dict(key='T_exhaustive', label='nlos_T exhaustive 8x8 x 8x8 laser, 512 bins',
         scene=lambda w: NLOS_T_EXH,
         defines=dict(res=8, bins=512), spp=256, block=(4, 4, 4, 4, 32)),
    dict(key='T_nee_wide', label='nlos_T confocal, NEE (no laser sampling), fov 60, no HGS',
         scene=lambda w: t_variant(w, 'T_nee_wide', laser_sampling=False, hgs=False, fov=60),
         defines=dict(res=16, bins=512), spp=4096, block=(4, 4, 16)),
    dict(key='T_nee_wide_hgs', label='nlos_T confocal, NEE, fov 60, HGS on',
         scene=lambda w: t_variant(w, 'T_nee_wide_hgs', laser_sampling=False, fov=60),
         defines=dict(res=16, bins=512), spp=256, block=(4, 4, 16)),
    dict(key='T_nee_narrow', label='nlos_T confocal, NEE, fov 0.2, no HGS',
         scene=lambda w: t_variant(w, 'T_nee_narrow', laser_sampling=False, hgs=False),
         defines=dict(res=16, bins=512), spp=256, block=(4, 4, 16)),
    dict(key='T_nohgs', label='nlos_T confocal, laser sampling, no HGS',
         scene=lambda w: t_variant(w, 'T_nohgs', hgs=False),
         defines=dict(res=16, bins=512), spp=4096, block=(4, 4, 16)),
    dict(key='T_afalb', label='nlos_T confocal, account_first_and_last_bounces, start 6.402',
         scene=lambda w: t_variant(w, 'T_afalb', afalb=True, start_opl=6.402, bin_width=0.008),
         defines=dict(res=16, bins=512), spp=256, block=(4, 4, 16)),
    # The same captures with the T at z = 2 (twice as far): every hidden point then sees
    # every lit point within 46 degrees of its normal, so these rows passed even before the
    # shadow-ray fix (see docs/results/nlos_agreement.md). Echoes from OPL 4.0.
    dict(key='T_confocal_far', label='nlos_T confocal, T at z=2, start 3.902',
         scene=lambda w: t_variant(w, 'T_confocal_far', tz=2, start_opl=3.902),
         defines=dict(res=16, bins=512), spp=256, block=(4, 4, 16)),
    dict(key='T_exhaustive_far', label='nlos_T exhaustive 8x8 x 8x8, T at z=2, start 3.902',
         scene=lambda w: t_variant(w, 'T_exhaustive_far', capture='exhaustive',
                                   exhaustive=True, tz=2, start_opl=3.902),
         defines=dict(res=8, bins=512), spp=256, block=(4, 4, 4, 4, 32)),
    dict(key='T_nohgs_far', label='nlos_T confocal, no HGS, T at z=2, start 3.902',
         scene=lambda w: t_variant(w, 'T_nohgs_far', hgs=False, tz=2, start_opl=3.902),
         defines=dict(res=16, bins=512), spp=4096, block=(4, 4, 16)),
    dict(key='T_afalb_far', label='nlos_T confocal, afalb, T at z=2, start 8.302',
         scene=lambda w: t_variant(w, 'T_afalb_far', afalb=True, tz=2, start_opl=8.302,
                                   bin_width=0.01),
         defines=dict(res=16, bins=512), spp=256, block=(4, 4, 16)),
    # The relay wall moved by 0.7 along x, a 32x32 grid: grid points on the wall's
    # diagonal (row == column) are aimed at the edge shared by its two triangles.
    dict(key='T_wall_shifted', label='nlos_T confocal 32x32, relay wall moved to x=0.7',
         scene=lambda w: t_variant(w, 'T_wall_shifted', wall_x=0.7),
         defines=dict(res=32, bins=512), spp=256, block=(4, 4, 16)),
    dict(key='Z_confocal', label='peer nlos_Z_confocal 8x8, 200 bins',
         scene=lambda w: PEER / 'nlos_Z_confocal.xml', defines={}, spp=1024,
         block=(2, 2, 10)),
    dict(key='Z_exhaustive', label='peer nlos_Z_exhaustive 8x8 x 8x8, 200 bins',
         scene=lambda w: PEER / 'nlos_Z_exhaustive.xml', defines={}, spp=256,
         block=(4, 4, 4, 4, 10)),
    dict(key='z_simple', label='nlos-z-simple (perspective, single) 32x32, 300 bins',
         scene=z_simple, defines={}, spp=1024, block=(8, 8, 15)),
    dict(key='Z_legacy', label='legacy nlos_Z.xml (single) 64x64, 300 bins',
         scene=lambda w: EX / 'nlos_Z.xml', defines={}, spp=256, block=(16, 16, 15)),
]


# ---------------------------------------------------------------- --probe
PROBE_XML = """<scene version="3.0.0">
    <default name="cx" value="0"/> <default name="cz" value="1"/>
    <default name="tx" value="0"/> <default name="ws" value="3"/> <default name="wx" value="0"/>
    <default name="t0" value="0"/> <default name="bw" value="0.01"/> <default name="nb" value="2000"/>
    <integrator type="transient_nlos_path">
        <string name="capture_type" value="single"/>
        <boolean name="nlos_laser_sampling" value="true"/>
        <boolean name="nlos_hidden_geometry_sampling" value="true"/>
        <string name="temporal_filter" value="box"/>
    </integrator>
    <emitter type="projector">
        <rgb name="irradiance" value="1.0"/> <float name="fov" value="0.2"/>
        <transform name="to_world"><lookat origin="-2, 0, 2" target="$tx, 0, 0" up="0, 1, 0"/></transform>
    </emitter>
    <shape type="rectangle" id="relay_wall">
        <transform name="to_world"><scale x="$ws" y="$ws"/> <translate x="$wx" y="0" z="0"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="1.0"/></bsdf>
        <sensor type="nlos_capture_meter">
            <point name="sensor_origin" x="-2" y="0" z="2"/>
            <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
            <film type="transient_hdr_film">
                <integer name="width" value="4"/> <integer name="height" value="4"/>
                <integer name="temporal_bins" value="$nb"/>
                <float name="start_opl" value="$t0"/> <float name="bin_width_opl" value="$bw"/>
                <rfilter type="box"/>
            </film>
        </sensor>
    </shape>
    <shape type="rectangle" id="patch">
        <bsdf type="diffuse"><rgb name="reflectance" value="1.0"/></bsdf>
        <transform name="to_world">
            <scale x="0.002" y="0.002"/> <rotate y="1" angle="180"/>
            <translate x="$cx" y="0" z="$cz"/>
        </transform>
    </shape>
</scene>
"""


def probe_render(tstat, work, defines):
    """The probe scene (single capture, 4x4 pixels, 16 spp) in both renderers."""
    xml = work / 'probe_patch.xml'
    xml.write_text(PROBE_XML)
    log = work / 'probe.log'
    out = work / 'probe.tstats'

    def tstat_x():
        cmd = [tstat, 'render', str(xml), '--out', str(out), '--seed', '1',
               '--pixel-sampling', 'independent', '--force']
        for k, v in defines.items():
            cmd += ['-D', f'{k}={v}']
        run(cmd, log)
        return np.load(out / 'x1.npy') / 16

    def mitr_x():
        return render_mitr(xml, defines, 16, 1, work / 'probe_m.npy', log, False)[0]
    return tstat_x, mitr_x


def probe(tstat, work):
    """Regression check for the laser-sampling shadow-ray bug (fixed in 11e593d).

    Single capture, a 4 mm hidden patch at (cx, 0, cz) facing the wall z = 0, the laser
    spot at (tx, 0, 0): bisects, between 5 and 80 degrees, the angle theta at the patch
    (normal to laser spot) beyond which tstat's transient is exactly zero. Before the fix
    it sat at the prediction of the offset-ray test, sin^2(theta) = cz / (1 + max|x|)
    (ray_epsilon = 1e-4 (1 + max|x|)): 35-55 degrees. Now it must be "none below 80". Also
    shows both renderers' sums 3 degrees beyond the old cut-off (16 spp, one seed: the
    ratio is noisy). Returns the number of rows with a cut-off."""
    import math
    print('| patch (cx, cz) | tstat zero beyond (deg) | old cut-off asin(sqrt(cz / (1 + max abs coord))) '
          '| tstat sum at +3 deg | mitransient sum at +3 deg | t/m |')
    print('|---|---|---|---|---|---|')
    bad = 0
    for cz, cx in [(0.5, 0.0), (1.0, 0.0), (2.0, 0.0), (1.0, 2.0)]:
        geo = lambda a: dict(cz=cz, cx=cx, tx=cx + cz * math.tan(math.radians(a)),
                             ws=max(3.0, cx + cz * math.tan(math.radians(a)) + 1))
        lo, hi = 5.0, 80.0
        for _ in range(12):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if probe_render(tstat, work, geo(mid))[0]().sum() > 0 else (lo, mid)
        pred = math.degrees(math.asin(math.sqrt(cz / (1 + max(abs(cx), cz)))))
        t_x, m_x = probe_render(tstat, work, geo(pred + 3))
        ts, ms = float(t_x().sum()), float(m_x().sum())
        cut = f'{lo:.2f}' if lo < 79.9 else 'none below 80'
        bad += lo < 79.9
        print(f'| ({cx:g}, {cz:g}) | {cut} | {pred:.2f} | {ts:.3g} | {ms:.3g} | '
              f'{ts / ms if ms else float("nan"):.3f} |')
    return bad


def onset(tstat, work):
    """Time offset between the renderers. The probe scene with a 1 mm relay wall (every
    wall point within 0.5 mm of (wx, 0, 0)) and the 4 mm patch at (wx, 0, cz) facing it,
    the laser spot next to the wall's centre: every one-bounce path has OPL 2 cz to within
    1e-5. 200 bins of 1e-5 around 2 cz; energy-weighted mean arrival - 2 cz, and the
    energy fraction before 2 cz, for each renderer. (Mitsuba moves a spawned ray's origin
    off the surface by 1500 * 2^-24 (1 + max|p|) = 8.9e-5 (1 + max|p|).)"""
    print('| wall centre wx, patch distance cz | tstat mean arrival - 2cz '
          '| tstat energy before 2cz | mitransient mean arrival - 2cz '
          '| mitransient energy before 2cz |')
    print('|---|---|---|---|---|')
    bw, nb = 1e-5, 200
    for wx, cz in ((0, 0.5), (0, 1.0), (0, 2.0), (1, 1.0), (3, 1.0)):
        t0 = 2 * cz - nb // 2 * bw
        # the laser spot 0.1 mm off the wall's centre: a ray aimed exactly at the centre
        # (on the diagonal edge between tstat's two triangles) may miss the wall
        d = dict(cz=cz, cx=wx, tx=wx + 1e-4, wx=wx, ws=0.0005, t0=f'{t0:.6f}', bw=bw, nb=nb)
        t_x, m_x = probe_render(tstat, work, d)
        row = [f'{wx:g}, {cz:g}']
        for x in (t_x(), m_x()):
            e = x.sum(axis=(0, 1, 3))
            c = t0 + (np.arange(nb) + 0.5) * bw - 2 * cz
            row += [f'{(e * c).sum() / e.sum():+.2e}', f'{e[:nb // 2].sum() / e.sum():.3f}']
        print('| ' + ' | '.join(row) + ' |')


# ---------------------------------------------------------------- rendering
def run(cmd, log, rss=None):
    """Runs cmd; with rss (a path), under /usr/bin/time, whose peak RSS (MB) is then
    returned as a third value (None without /usr/bin/time)."""
    timed = rss is not None and TIME.exists()
    full = [str(TIME), '-f', '%M', '-o', str(rss)] + list(map(str, cmd)) if timed else cmd
    t0 = time.perf_counter()
    r = subprocess.run(full, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    with open(log, 'a') as f:
        f.write('$ ' + ' '.join(map(str, cmd)) + '\n' + r.stdout + r.stderr + '\n')
    if r.returncode != 0:
        sys.exit(f'failed ({r.returncode}): {" ".join(map(str, cmd))}\n{r.stdout}\n{r.stderr}')
    if rss is None:
        return r.stdout + r.stderr, wall
    mb = float(Path(rss).read_text().split()[-1]) / 1024 if timed else None
    return r.stdout + r.stderr, wall, mb


def render_tstat(tstat, scene, defines, spp, seed, out, log):
    cmd = [tstat, 'render', str(scene), '--out', str(out), '--spp', str(spp),
           '--seed', str(seed), '--pixel-sampling', 'independent', '--force']
    for k, v in defines.items():
        cmd += ['-D', f'{k}={v}']
    _, wall, rss = run(cmd, log, rss=str(out) + '.rss')
    man = json.loads((out / 'manifest.json').read_text())
    x = np.load(out / 'x1.npy') / man['spp']
    nl = man.get('nlos') or {}
    if nl.get('capture') == 'exhaustive':
        lw, lh = nl['laser_grid']
        rows, sx, t, c = x.shape
        sy = rows // (lw * lh)
        # bundle row (ly*Lw+lx)*Sy + sy  ->  mit[sy, sx, ly, lx]
        x = x.reshape(lh, lw, sy, sx, t, c).transpose(2, 3, 0, 1, 4, 5)
    return x, man['render_seconds'], wall, rss


def render_mitr(scene, defines, spp, seed, out, log, warmup):
    cmd = [sys.executable, str(MITR), str(scene), '--out', str(out), '--spp', str(spp),
           '--seed', str(seed)]
    for k, v in defines.items():
        cmd += ['-D', f'{k}={v}']
    if warmup:
        cmd.append('--warmup')
    txt, wall, rss = run(cmd, log, rss=str(out) + '.rss')
    m = re.search(r'(?<!warm-up )render wall time: ([0-9.]+) s', txt)
    return np.load(out).astype(np.float64), float(m.group(1)), wall, rss


# ---------------------------------------------------------------- metrics
def per_bin(a):
    return a.reshape(-1, a.shape[-2], a.shape[-1]).sum(axis=(0, 2))


def blocks(a, bs):
    a = a.sum(axis=-1)                      # channels
    assert len(bs) == a.ndim, (bs, a.shape)
    shp = []
    for n, b in zip(a.shape, bs):
        assert n % b == 0, (a.shape, bs)
        shp += [n // b, b]
    return a.reshape(shp).sum(axis=tuple(range(1, len(shp), 2))).ravel()


def rel(a, b, mask):
    return np.abs(a[mask] - b[mask]) / b[mask]


def nz_range(a):
    e = per_bin(a)
    nz = np.nonzero(e)[0]
    return (int(nz[0]), int(nz[-1])) if len(nz) else (None, None)


def pixel_totals(a):
    # independent unit: the sensor pixel (axes 0, 1 of mitransient's layout)
    return a.reshape(a.shape[0], a.shape[1], -1).sum(axis=-1)


def mean_arrival(a):
    """Energy-weighted mean bin (centre) per pixel, and the pixels' energies."""
    e = a.sum(axis=-1).reshape(-1, a.shape[-2])
    tot = e.sum(axis=1)
    k = np.arange(a.shape[-2]) + 0.5
    with np.errstate(invalid='ignore', divide='ignore'):
        return (e * k).sum(axis=1) / tot, tot


def metrics(t1, t2, m1, m2, bs):
    out = {}
    Et, Et2, Em1, Em2 = (float(x.sum()) for x in (t1, t2, m1, m2))
    out['E'] = (Et, Et2, Em1, Em2)
    if Em1 == 0.0:
        out['zero'] = True
        return out
    out['zero'] = False
    out['Et_m1'] = Et / Em1
    out['Em2_m1'] = Em2 / Em1
    out['Et2_t1'] = Et2 / Et if Et else float('nan')
    var_t = 0.5 * float(((pixel_totals(t1) - pixel_totals(t2)) ** 2).sum())
    var_m = 0.5 * float(((pixel_totals(m1) - pixel_totals(m2)) ** 2).sum())
    out['zE'] = (Et - Em1) / np.sqrt(var_t + var_m) if var_t + var_m > 0 else float('nan')
    out['seE_rel'] = np.sqrt(var_m) / Em1
    bt, b1, b2 = per_bin(t1), per_bin(m1), per_bin(m2)
    mask = b1 > 0.01 * b1.max()
    out['bins_t'] = float(rel(bt, b1, mask).max())
    out['bins_m'] = float(rel(b2, b1, mask).max())
    out['nbins'] = int(mask.sum())
    kt, k1, k2 = blocks(t1, bs), blocks(m1, bs), blocks(m2, bs)
    mask = k1 > 0.01 * k1.max()
    out['blk_t'] = float(np.percentile(rel(kt, k1, mask), 95))
    out['blk_m'] = float(np.percentile(rel(k2, k1, mask), 95))
    out['nblk'] = (int(mask.sum()), int(k1.size))
    out['nz'] = (nz_range(t1), nz_range(m1), nz_range(m2))
    (at, et), (at2, et2), (a1, e1), (a2, e2) = (mean_arrival(x) for x in (t1, t2, m1, m2))
    ok = (et > 0) & (et2 > 0) & (e1 > 0) & (e2 > 0)
    w = e1[ok] / e1[ok].sum()
    out['arr_t'] = float((w * (at[ok] - a1[ok])).sum())
    out['arr_m'] = float((w * (a2[ok] - a1[ok])).sum())
    # variance from the seeds per sensor pixel, the independent unit (mitransient's
    # exhaustive captures reuse one path for all laser points of a sensor pixel)
    n_px = t1.shape[0] * t1.shape[1]
    px = np.repeat(np.arange(n_px), at.size // n_px)[ok]

    def seed_var(a, b):
        return 0.5 * float((np.bincount(px, w * (a[ok] - b[ok]), n_px) ** 2).sum())
    out['arr_se'] = float(np.sqrt(seed_var(at, at2) + seed_var(a1, a2)))
    # units (pixels; (sensor, laser) pairs) that are zero in both seeds of one renderer
    # and bright (> 10% of the median lit unit) in both of the other: a systematic hole,
    # not the rare hits of a pixel that barely covers the wall's silhouette
    lit = 0.1 * np.median(e1[e1 > 0])
    out['dead_t'] = int(((et + et2 == 0) & (e1 > lit) & (e2 > lit)).sum())
    out['dead_m'] = int(((e1 + e2 == 0) & (et > lit) & (et2 > lit)).sum())
    fails = []
    if not abs(out['zE']) <= 3:
        fails.append(f"zE={out['zE']:.1f}")
    if out['bins_t'] > 1.5 * out['bins_m']:
        fails.append('bins')
    if out['blk_t'] > 1.5 * out['blk_m']:
        fails.append('blk95')
    if out['dead_t'] or out['dead_m']:
        fails.append(f"dark pixels t {out['dead_t']}, m {out['dead_m']}")
    f_t, f_1, f_2 = out['nz'][0][0], out['nz'][1][0], out['nz'][2][0]
    if f_t is None or f_t < min(f_1, f_2) - 2 or f_t > max(f_1, f_2) + 2:
        fails.append('first bin')
    out['verdict'] = 'agrees' if not fails else 'DIFFERS: ' + ', '.join(fails)
    return out


# ---------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--spp', type=int, default=0, help='spp for every case (0: per-case default)')
    ap.add_argument('--tstat', default=str(ROOT / 'target' / 'release' / 'tstat'),
                    help='the tstat binary (default: target/release/tstat)')
    ap.add_argument('--only', default='', help='comma-separated case keys')
    ap.add_argument('--work', default=str(Path(tempfile.gettempdir()) / 'nlos_agree_work'),
                    help='scratch folder for scene variants, renders and runs.log')
    ap.add_argument('--keep', action='store_true', help='keep bundles and .npy files')
    ap.add_argument('--json', default='', help='also write the raw metrics here')
    ap.add_argument('--probe', action='store_true',
                    help='only run the regression check for the fixed laser-sampling '
                         'shadow-ray bug: bisect the angle beyond which tstat gives exactly '
                         'zero (must be "none below 80"; exit status 1 otherwise; see probe())')
    ap.add_argument('--onset', action='store_true',
                    help='only measure both renderers\' echo arrival against the exact OPL '
                         '(mitransient times segments from its offset ray origins; see onset())')
    a = ap.parse_args()

    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    if a.probe:
        sys.exit(1 if probe(a.tstat, work) else 0)
    if a.onset:
        onset(a.tstat, work)
        return
    log = work / 'runs.log'
    log.write_text('')
    only = set(filter(None, a.only.split(',')))
    results = []
    for case in CASES:
        if only and case['key'] not in only:
            continue
        spp = a.spp or case['spp']
        scene = case['scene'](work)
        d = work / case['key']
        d.mkdir(exist_ok=True)
        print(f"[{case['key']}] {scene} spp {spp}", file=sys.stderr, flush=True)
        t1, tsec, twall, trss = render_tstat(a.tstat, scene, case['defines'], spp, 1,
                                             d / 't1.tstats', log)
        t2 = render_tstat(a.tstat, scene, case['defines'], spp, 2, d / 't2.tstats', log)[0]
        m1, msec, mwall, mrss = render_mitr(scene, case['defines'], spp, 1, d / 'm1.npy', log,
                                            True)
        m2 = render_mitr(scene, case['defines'], spp, 2, d / 'm2.npy', log, False)[0]
        assert t1.shape == m1.shape, (case['key'], t1.shape, m1.shape)
        r = metrics(t1, t2, m1, m2, case['block'])
        r.update(key=case['key'], label=case['label'], spp=spp, shape=list(m1.shape),
                 block=list(case['block']), scene=str(scene), defines=case['defines'],
                 t_sec=tsec, t_wall=twall, m_sec=msec, m_wall=mwall, t_rss=trss, m_rss=mrss)
        results.append(r)
        if not a.keep:
            shutil.rmtree(d)

    def f(x, n=3):
        return f'{x:.{n}f}'

    print('| case | spp | E t/m1 | E m2/m1 | zE | bins t-m1 | bins m2-m1 | blk95 t-m1 '
          '| blk95 m2-m1 | verdict |')
    print('|---|---|---|---|---|---|---|---|---|---|')
    for r in results:
        if r['zero']:
            print(f"| {r['label']} | {r['spp']} | sums t {r['E'][0]:.3g}, m1 {r['E'][2]:.3g}, "
                  f"m2 {r['E'][3]:.3g} | | | | | | | "
                  f"{'agrees (all zero)' if r['E'][0] == 0 else 'DIFFERS (mit zero)'} |")
            continue
        print(f"| {r['label']} | {r['spp']} | {f(r['Et_m1'], 4)} | {f(r['Em2_m1'], 4)} | "
              f"{r['zE']:+.2f} | {f(r['bins_t'])} | {f(r['bins_m'])} | {f(r['blk_t'])} | "
              f"{f(r['blk_m'])} | {r['verdict']} |")
    print()
    print('| case | shape (mit layout) | block | bins>1% / blocks>1% | nz bins t1 / m1 / m2 '
          '| arrival t1-m1 (m2-m1), bins | dark px t / m | sum m1 | tstat render (process) s '
          '| mitransient render s | peak RSS MB tstat / mit |')
    print('|---|---|---|---|---|---|---|---|---|---|---|')
    for r in results:
        shape = 'x'.join(map(str, r['shape']))
        blk = 'x'.join(map(str, r['block']))
        if r['zero']:
            cnt, nz, arr, dark = '-', '-', '-', '-'
        else:
            cnt = f"{r['nbins']} / {r['nblk'][0]} of {r['nblk'][1]}"
            nz = ' / '.join(f'{x[0]}-{x[1]}' for x in r['nz'])
            arr = f"{r['arr_t']:+.3f} ± {r['arr_se']:.3f} ({r['arr_m']:+.3f})"
            dark = f"{r['dead_t']} / {r['dead_m']}"
        rss = ' / '.join('-' if x is None else f'{x:.0f}' for x in (r['t_rss'], r['m_rss']))
        print(f"| {r['key']} | {shape} | {blk} | {cnt} | {nz} | {arr} | {dark} | {r['E'][2]:.5g} | "
              f"{r['t_sec']:.2f} ({r['t_wall']:.2f}) | {r['m_sec']:.2f} | {rss} |")
    if a.json:
        Path(a.json).write_text(json.dumps(results, indent=1, default=str))


if __name__ == '__main__':
    main()
