#!/usr/bin/env python3
"""Per-component Stokes agreement of tstat's `--mode mono_polarized` (or
`--mode spectral_polarized`) steady image with Mitsuba 3's own `stokes` integrator
(llvm_ad_mono_polarized or llvm_ad_spectral_polarized, `path` inside), which writes
S0..S3 (of each sRGB channel when spectral) in the sensor's frame, the frame tstat
writes (docs/polarization.md).

Each scene is copied at 32 px wide (as scripts/agreement.py copies it); for Mitsuba its
transient integrator becomes `stokes(path)` with the same max_depth and its transient
film an `hdrfilm` of the same size. Mitsuba renders at seeds 1 and 2, tstat at seed 1;
per component k the table gives |mean S_k tstat - Mitsuba seed 1| over the mean S0,
and the same for seed 2 against seed 1 (Mitsuba's own spread), and the largest
difference of 8x8-pixel blocks over the seed-1 S0 block (floor 1% of its largest).

    python3 scripts/agree_stokes.py --spp 512 SCENE...
    python3 scripts/agree_stokes.py --mode spectral_polarized --spp 512 SCENE...

Spectral: the twelve components S_k.R, S_k.G, S_k.B, each against the mean S0 of its
own colour; the table gives per Stokes component the worst of the three colours.
"""
import argparse, json, os, re, subprocess, sys, tempfile
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import agree_wild, agreement  # noqa: E402

MIT = r"""
import os, sys, glob, json
libs = glob.glob('/usr/lib/x86_64-linux-gnu/libLLVM-19.so*') + glob.glob('/usr/lib/llvm-19/lib/libLLVM*.so*')
if libs: os.environ.setdefault('DRJIT_LIBLLVM_PATH', libs[0])
import mitsuba as mi, numpy as np
mi.set_variant('llvm_ad_' + sys.argv[7])
spectral = sys.argv[7] == 'spectral_polarized'
for folder in json.loads(sys.argv[5]):
    mi.file_resolver().append(folder)
scene = mi.load_file(sys.argv[1], **json.loads(sys.argv[4]))
img = np.array(mi.render(scene, spp=int(sys.argv[2]), seed=int(sys.argv[3])))
names = scene.integrator().aov_names()
# The film's own channel(s) come first, then the AOVs S0.R, S0.G, S0.B, S1.R, ...
first = img.shape[-1] - len(names)
# tstat's order: S0..S3 of R (mono: its one band), then of G, then of B.
colours = "RGB" if spectral else "R"
out = np.stack([img[..., first + names.index(f"S{k}.{c}")] for c in colours for k in range(4)], -1)
np.save(sys.argv[6], out)
"""


def to_stokes(xml, spectral=False):
    m = re.search(r'<integer name="max_depth" value="([^"]+)"', xml)
    depth = m.group(1) if m else "-1"
    xml = re.sub(r'<integrator type="transient_\w+"[^>]*?(/>|>.*?</integrator>)',
                 f'<integrator type="stokes"><integrator type="path"><integer name="max_depth" value="{depth}"/></integrator></integrator>',
                 xml, count=1, flags=re.S)
    xml = xml.replace('type="transient_hdr_film"', 'type="hdrfilm"')
    xml = re.sub(r'\s*<(integer|float|boolean) name="(temporal_bins|start_opl|bin_width_opl|auto_detect_bins|camera_unwarp)"[^>]*/>', '', xml)
    if spectral:
        return xml.replace('<film type="hdrfilm">', '<film type="hdrfilm"><string name="pixel_format" value="rgb"/>', 1)
    return xml.replace('<film type="hdrfilm">', '<film type="hdrfilm"><string name="pixel_format" value="luminance"/>', 1)


def measure(path, args, tmp):
    copy, needed = agree_wild.small_copy(path, args.width, tmp)
    if copy is None:
        copy, needed = agreement.small_copy_included(path, args.width, tmp)
    search = list(args.search)
    m = re.search(r"^(.*mitsuba-renderer_mitsuba-data)" + re.escape(os.sep), path)
    if m:
        search.append(os.path.join(m.group(1), "common"))
    for f in os.listdir(tmp):
        if f.endswith(".xml"):
            p = os.path.join(tmp, f)
            s = open(p).read()
            open(os.path.join(tmp, "stokes_" + f), "w").write(to_stokes(s, args.mode == "spectral_polarized"))
    stokes_copy = os.path.join(tmp, "stokes_" + os.path.basename(copy))
    # Included files are referenced by name: give the stokes copy its own includes.
    s = open(stokes_copy).read()
    for f in os.listdir(tmp):
        if f.endswith(".xml") and not f.startswith("stokes_"):
            s = s.replace(f'"{f}"', f'"stokes_{f}"').replace(f'/{f}"', f'/stokes_{f}"')
    open(stokes_copy, "w").write(s)
    ms = []
    for seed in (1, 2):
        out = os.path.join(tmp, f"m{seed}.npy")
        r = subprocess.run([sys.executable, "-c", MIT, stokes_copy, str(args.spp), str(seed),
                            json.dumps(needed), json.dumps(search), out, args.mode], capture_output=True, text=True)
        if r.returncode:
            return {"skip": (r.stderr.strip().splitlines() or ["?"])[-1][:200]}
        ms.append(np.load(out))
    cmd = [args.tstat, "render", copy, "--spp", str(args.spp), "--seed", "1", "--mode", args.mode,
           "--out", os.path.join(tmp, "t.tstats"), "--force"]
    for k, v in needed.items():
        cmd += ["-D", f"{k}={v}"]
    for f in search:
        cmd += ["-a", f]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode:
        return {"skip": r.stderr.strip()[-200:]}
    t = np.load(os.path.join(tmp, "t.tstats", "steady.npy"))
    m1, m2 = ms
    t = t.reshape(t.shape[0], t.shape[1], -1)
    h, w = t.shape[:2]
    b = (min(8, h), min(8, w))
    blk = lambda x, k: agree_wild.blocks(x[..., k:k + 1], *b)
    rows = []
    for c in range(t.shape[-1] // 4):
        s0 = max(float(m1[..., 4 * c].mean()), 1e-12)
        den = np.maximum(blk(m1, 4 * c), blk(m1, 4 * c).max() * 0.01)
        row = []
        for k in range(4 * c, 4 * c + 4):
            row.append({
                "dev": float(abs(t[..., k].mean() - m1[..., k].mean()) / s0),
                "dev_mit": float(abs(m2[..., k].mean() - m1[..., k].mean()) / s0),
                "block": float((np.abs(blk(t, k) - blk(m1, k)) / den).max()),
                "block_mit": float((np.abs(blk(m2, k) - blk(m1, k)) / den).max()),
            })
        rows.append(row)
    return {"colours": rows}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--spp", type=int, default=512)
    ap.add_argument("--width", type=int, default=32)
    ap.add_argument("--mode", choices=["mono_polarized", "spectral_polarized"], default="mono_polarized")
    ap.add_argument("-a", dest="search", action="append", default=[])
    ap.add_argument("--tstat", default=os.path.join(agreement.ROOT, "target", "release", "tstat"))
    args = ap.parse_args()
    print("| scene | S0 | S1 | S2 | S3 | verdict |")
    print("|---|---|---|---|---|---|")
    bad = 0
    for path in args.scenes:
        with tempfile.TemporaryDirectory() as tmp:
            r = measure(os.path.abspath(path), args, tmp)
        name = os.path.relpath(os.path.abspath(path), os.path.join(agreement.ROOT, ".."))
        if "skip" in r:
            print(f"| {name} | skipped: {r['skip']} | | | | |")
            continue
        within = lambda c: c["dev"] <= max(3 * c["dev_mit"], 0.005) and c["block"] <= max(2 * c["block_mit"], 0.05)
        ok = all(within(c) for row in r["colours"] for c in row)
        bad += not ok
        # Per Stokes component, the colour furthest from its bound.
        worst = [max((row[k] for row in r["colours"]),
                     key=lambda c: max(c["dev"] / max(3 * c["dev_mit"], 0.005), c["block"] / max(2 * c["block_mit"], 0.05)))
                 for k in range(4)]
        cells = " | ".join(f"{c['dev']:.4f} / {c['dev_mit']:.4f}; {c['block']:.3f} / {c['block_mit']:.3f}"
                           for c in worst)
        print(f"| {name} | {cells} | {'within' if ok else 'OPEN'} |", flush=True)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
