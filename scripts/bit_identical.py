#!/usr/bin/env python3
"""Fingerprint what every scene renders, to show a refactor changes no bit.

Renders every bundled scene (scenes/*.xml), the shared scenes and the public scenes in
../shared/wild-scenes (as scripts/wild_scenes.py lists them) at a small size, and records
the SHA-256 of each bundle's arrays and of `tstat check`'s output (stdout + stderr + exit
code). `--save FILE` writes the fingerprints; `--compare FILE` re-renders and lists every
scene whose bits or messages differ (exit 1 if any).

    python3 scripts/bit_identical.py --tstat /tmp/tstat_before --save /tmp/before.json
    python3 scripts/bit_identical.py --compare /tmp/before.json

Not part of `cargo test`: a clone of the repository has no ../shared.
"""
import argparse
import glob
import hashlib
import json
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import wild_scenes  # noqa: E402


def digest(path):
    h = hashlib.sha256()
    for name in sorted(os.listdir(path)):
        if name.endswith(".npy"):
            h.update(name.encode())
            h.update(open(os.path.join(path, name), "rb").read())
    return h.hexdigest()


def fingerprint(tstat, scene, extra, tmp, timeout):
    c = subprocess.run([tstat, "check", scene] + extra, capture_output=True, text=True)
    check = hashlib.sha256((c.stdout + c.stderr + str(c.returncode)).encode()).hexdigest()
    out = os.path.join(tmp, "s.tstats")
    subprocess.run(["rm", "-rf", out])
    cmd = [tstat, "render", scene, "--out", out, "--width", "24", "--spp", "4",
           "--bins", "16", "--threads", "2"] + extra
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"check": check, "render": "timeout"}
    if r.returncode != 0:
        missing = "has no <default" in r.stderr
        if missing:
            for k, v in wild_scenes.PARAMETERS.items():
                cmd += ["-D", f"{k}={v}"]
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if r.returncode != 0:
        return {"check": check, "render": "error: " + wild_scenes.first_error(r.stderr)}
    return {"check": check, "render": digest(out)}


def main():
    ap = argparse.ArgumentParser()
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--tstat", default=os.path.join(here, "..", "target", "release", "tstat"))
    ap.add_argument("--wild", default=os.path.join(here, "..", "..", "shared", "wild-scenes"))
    ap.add_argument("--timeout", type=float, default=120)
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--save")
    g.add_argument("--compare")
    a = ap.parse_args()
    root = os.path.join(here, "..")
    files = sorted(glob.glob(os.path.join(root, "scenes", "*.xml")))
    files += sorted(glob.glob(os.path.join(root, "..", "shared", "scenes", "*.xml")))
    wild = wild_scenes.scenes(a.wild) if os.path.isdir(a.wild) else []
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        for f in files + wild:
            extra = wild_scenes.search_folders(a.wild, f) if f in wild else []
            key = os.path.relpath(os.path.realpath(f), os.path.realpath(os.path.join(root, "..")))
            result[key] = fingerprint(a.tstat, f, extra, tmp, a.timeout)
    if a.save:
        json.dump(result, open(a.save, "w"), indent=1, sort_keys=True)
        bad = sum(1 for v in result.values() if not v["render"][0].isalnum() or v["render"].startswith("error"))
        print(f"{len(result)} scenes fingerprinted ({bad} do not render) -> {a.save}")
        return
    before = json.load(open(a.compare))
    diffs = [k for k in sorted(set(before) | set(result)) if before.get(k) != result.get(k)]
    for k in diffs:
        print(f"DIFFERS {k}\n   before {before.get(k)}\n   after  {result.get(k)}")
    print(f"{len(result)} scenes compared, {len(diffs)} differ")
    sys.exit(1 if diffs else 0)


if __name__ == "__main__":
    main()
