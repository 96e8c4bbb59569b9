#!/usr/bin/env python3
"""Render an NLOS scene with mitransient 1.3.1 and save the transient as .npy.

usage: python3 mitr_nlos.py SCENE.xml --out OUT.npy [--spp N] [--seed S]
                            [-D key=value ...] [--warmup] [--legacy convert|strip|off]
                            [--print-targets] [--steady-out STEADY.npy]

* Parameters are passed as mi.load_file(path, **defines) (XML `$key` / <default>).
* Output: float32 transient in its native mitransient layout:
    single / confocal : (height, width, T, C)
    exhaustive        : (height, width, laser_scan_height, laser_scan_width, T, C)
  (C = 3 for *_rgb variants; alpha/weight channels are already removed by develop()).
* The printed render wall time covers mi.render + dr.eval + dr.sync_thread only
  (use --warmup to render once beforehand so JIT compilation is excluded).
* Legacy scenes (mitransient <= 1.1 style, e.g. examples/*/nlos_Z.xml) carry
  `confocal`, `laser_origin`, `laser_lookat_pixel` (and sometimes a nested <emitter>
  or a sensor-level <rfilter>) inside nlos_capture_meter; mitsuba 3.9.1 REJECTS them
  ("Found N unreferenced properties in sensor plugin"). Only if mi.load_file fails
  with that error, the XML is rewritten in memory (props removed, nested emitter
  moved to scene level, stray rfilter moved into the film) and loaded with
  mi.load_string(xml, **defines). With --legacy convert (default) the projector is
  then placed at laser_origin and aimed at the relay-wall point of laser_lookat_pixel,
  reproducing the old semantics. With --legacy strip the projector stays where the
  XML puts it (for examples/transient-nlos/nlos_Z.xml: at the origin looking +z,
  which makes prepare() fail with "The emitter is not pointing at the scene!").
  `account_first_and_last_bounces` on the sensor is left alone: 1.3.1 accepts it with
  a deprecation warning and IGNORES it (the integrator's flag, default false, is used).
"""
import argparse
import os
import re
import sys
import time
import xml.etree.ElementTree as ET

import numpy as np
import mitsuba as mi

mi.set_variant('llvm_ad_rgb')
import drjit as dr  # noqa: E402
import mitransient as mitr  # noqa: E402,F401

LEGACY_SENSOR_PROPS = ('confocal', 'laser_origin', 'laser_lookat_pixel', 'laser_lookat_3d')


def parse_defines(items):
    out = {}
    for it in items or []:
        if '=' not in it:
            sys.exit(f'bad -D {it!r}, expected key=value')
        k, v = it.split('=', 1)
        out[k.strip()] = v.strip()
    return out


def _vec(el, defines):
    def val(v):
        if v.startswith('$'):
            v = defines.get(v[1:], v)
        return float(v)
    if el.get('value') is not None:
        return [val(x) for x in re.split(r'[,\s]+', el.get('value').strip())]
    return [val(el.get(k, '0')) for k in ('x', 'y', 'z')]


def rewrite_legacy_xml(path, defines):
    """Rewrite a pre-1.2 mitransient NLOS scene so mitsuba 3.9.1 accepts it.
    Returns (xml_string, list_of_changes, legacy_laser_dict)."""
    tree = ET.parse(path)
    root = tree.getroot()
    changes, laser = [], {}
    for shape in root.iter('shape'):
        for sensor in [c for c in shape
                       if c.tag == 'sensor' and c.get('type') == 'nlos_capture_meter']:
            film = next((c for c in sensor if c.tag == 'film'), None)
            for child in list(sensor):
                name = child.get('name')
                if name in LEGACY_SENSOR_PROPS:
                    sensor.remove(child)
                    changes.append(f'removed <{child.tag} name="{name}"> from nlos_capture_meter')
                    if name == 'confocal':
                        laser['confocal'] = child.get('value')
                    else:
                        laser[name] = _vec(child, defines)
                elif child.tag == 'emitter':
                    sensor.remove(child)
                    root.append(child)
                    changes.append(f'moved <emitter type="{child.get("type")}"> '
                                   'from inside the sensor to scene level')
                elif child.tag == 'rfilter':
                    sensor.remove(child)
                    if film is not None and not any(c.tag == 'rfilter' for c in film):
                        film.append(child)
                        changes.append('moved sensor-level <rfilter> into the <film>')
                    else:
                        changes.append('removed sensor-level <rfilter>')
    return ET.tostring(root, encoding='unicode'), changes, laser


def aim_legacy_laser(scene, laser):
    """Old nlos_capture_meter semantics (mitransient <= 1.1): the projector sits at
    laser_origin and looks (up=(0,1,0)) at relay_wall.sample_position(laser_lookat_pixel /
    film_size) (no +0.5; used only if both pixel coords > 0), else at laser_lookat_3d."""
    if laser.get('confocal', 'false').lower() == 'true':
        print('[mitr_nlos] WARNING: legacy confocal=true dropped; use the integrator '
              'capture_type="confocal" instead', flush=True)
    if 'laser_origin' not in laser and 'laser_lookat_pixel' not in laser \
            and 'laser_lookat_3d' not in laser:
        return
    sensor = scene.sensors()[0]
    wall = sensor.get_shape()
    origin = laser.get('laser_origin', [0.0, 0.0, 0.0])
    px = laser.get('laser_lookat_pixel', [-1, -1, 0])
    if px[0] > 0 and px[1] > 0:
        fs = sensor.film().size()
        uv = mi.Point2f(px[0] / fs[0], px[1] / fs[1])
        p = wall.sample_position(0.0, uv, True).p
        target = [float(p.x[0]), float(p.y[0]), float(p.z[0])]
        how = f'laser_lookat_pixel ({px[0]:g}, {px[1]:g}) / film {fs[0]}x{fs[1]}'
    else:
        target = laser.get('laser_lookat_3d', [0.0, 0.0, 0.0])
        how = 'laser_lookat_3d'
    emitter = scene.emitters()[0]
    params = mi.traverse(emitter)
    params['to_world'] = mi.ScalarTransform4f().look_at(origin=origin, target=target, up=[0, 1, 0])
    params.update()
    print(f'[mitr_nlos] legacy laser: projector placed at {origin}, aimed at {target} ({how})',
          flush=True)


def load_scene(path, defines, legacy='convert'):
    try:
        return mi.load_file(path, **defines)
    except RuntimeError as e:
        msg = str(e)
        if legacy == 'off' or 'unreferenced propert' not in msg:
            raise
        print('[mitr_nlos] mitsuba rejected the scene:\n  '
              + msg.strip().replace('\n', '\n  '), flush=True)
    xml, changes, laser = rewrite_legacy_xml(path, defines)
    for c in changes:
        print(f'[mitr_nlos] legacy rewrite: {c}', flush=True)
    # relative paths (e.g. ./Z.obj) must resolve against the scene folder
    mi.file_resolver().prepend(os.path.dirname(os.path.abspath(path)))
    scene = mi.load_string(xml, **defines)
    if legacy == 'convert':
        aim_legacy_laser(scene, laser)
    return scene


def render(scene, spp, seed):
    dr.sync_thread()
    t0 = time.perf_counter()
    steady, transient = mi.render(scene, spp=spp, seed=seed)
    dr.eval(steady, transient)
    dr.sync_thread()
    return time.perf_counter() - t0, steady, transient


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('scene')
    ap.add_argument('--out', required=True)
    ap.add_argument('--spp', type=int, default=0,
                    help='0 = use the sampler sample_count from the XML')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('-D', dest='defines', action='append', default=[],
                    metavar='key=value')
    ap.add_argument('--warmup', action='store_true',
                    help='render once (seed+1) before the timed render, so JIT '
                         'compilation is excluded from the reported time')
    ap.add_argument('--legacy', choices=['convert', 'strip', 'off'], default='convert',
                    help='if mitsuba rejects legacy (<=1.1) nlos_capture_meter properties: '
                         'convert = rewrite XML and re-aim the projector from '
                         'laser_origin/laser_lookat_pixel (old semantics); '
                         'strip = rewrite XML only; off = fail')
    ap.add_argument('--print-targets', action='store_true',
                    help='print integrator.sensor_targets / laser_targets after rendering')
    ap.add_argument('--steady-out', default=None)
    a = ap.parse_args()

    defines = parse_defines(a.defines)
    t0 = time.perf_counter()
    scene = load_scene(a.scene, defines, legacy=a.legacy)
    print(f'load time: {time.perf_counter() - t0:.3f} s', flush=True)

    if a.warmup:
        tw, ws, wt = render(scene, a.spp, a.seed + 1)
        del ws, wt  # release the warm-up film memory before the timed render
        print(f'warm-up render wall time (incl. JIT / kernel-cache load): {tw:.3f} s', flush=True)
    t, steady, transient = render(scene, a.spp, a.seed)
    print(f'render wall time: {t:.3f} s', flush=True)

    tr = np.asarray(transient, dtype=np.float32)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    np.save(a.out, tr)
    print(f'shape: {tr.shape}')
    print(f'sum: {float(np.sum(tr, dtype=np.float64)):.9g}')
    if a.steady_out:
        np.save(a.steady_out, np.asarray(steady, dtype=np.float32))
    if a.print_targets:
        integ = scene.integrator()
        for name in ('sensor_targets', 'laser_targets'):
            if hasattr(integ, name):
                v = np.array(getattr(integ, name))
                v = v.T if (v.ndim == 2 and v.shape[0] == 3) else v
                print(f'{name} ({v.shape[0]} points, flat index order):\n'
                      f'{np.array2string(v, precision=4, suppress_small=True)}')


if __name__ == '__main__':
    main()
