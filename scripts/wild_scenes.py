#!/usr/bin/env python3
"""Load and render every public scene in ../shared/wild-scenes with tstat.

For each scene listed in the folder's README (transient scenes as published, steady
ones through their NAME_transient.xml conversion), runs `tstat check` (when the binary
has it) and a tiny render (16 px wide, 4 spp, 8 bins), then prints how many load and
render, and the error messages ranked by how many scenes they block.

    python3 scripts/wild_scenes.py [--tstat target/release/tstat] [--wild ../shared/wild-scenes]
                                   [--timeout 120] [--list]

Not part of `cargo test`: a clone of the repository has no ../shared.
"""
import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile


def scenes(wild):
    rows = []
    readme = open(os.path.join(wild, "README.md"), encoding="utf-8").read()
    for line in readme.splitlines():
        m = re.match(r"\| (\S+) \| (\S+\.xml)(?: \(from [^)]*\))? \| (.*) \|$", line)
        if not m:
            continue
        label, path, how = m.groups()
        if how.startswith("converted"):
            conv = re.search(r"`([^`]+)`", how).group(1)
            path = os.path.join(os.path.dirname(path), conv)
        rows.append(os.path.join(wild, label, path))
    return rows


# Values for scene parameters that public scenes leave to the caller.
PARAMETERS = {"spp": "4", "max_depth": "8", "rr_depth": "5", "res": "16", "resx": "16", "resy": "16",
              "integrator": "transient_path"}


def run(cmd, timeout):
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False, f"error: timed out after {timeout:.0f} s"
    if r.returncode == 0:
        return True, ""
    return False, first_error(r.stderr)


def first_error(stderr):
    for line in stderr.splitlines():
        if line.startswith("error:"):
            return line
    return stderr.strip().splitlines()[-1] if stderr.strip() else "(no message)"


def normalise(msg):
    """The message without file, line and numbers, to rank causes."""
    msg = re.sub(r"^error: \S+?:\d+: ", "error: ", msg)
    msg = re.sub(r"'[^']*'", "'...'", msg)
    msg = re.sub(r"\d+(\.\d+)?", "N", msg)
    return msg[:160]


def search_folders(wild, scene):
    """`-a` folders a scene is published for: mitsuba-data's docs and tests are
    rendered with `-a common` (its docs build), which holds shared meshes and textures."""
    label = os.path.relpath(scene, wild).split(os.sep)[0]
    common = os.path.join(wild, label, "common")
    if label == "mitsuba-renderer_mitsuba-data" and os.path.isdir(common):
        return ["-a", common]
    return []


def main():
    ap = argparse.ArgumentParser()
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--tstat", default=os.path.join(here, "..", "target", "release", "tstat"))
    ap.add_argument("--wild", default=os.path.join(here, "..", "..", "shared", "wild-scenes"))
    ap.add_argument("--timeout", type=float, default=120)
    ap.add_argument("--list", action="store_true", help="print every scene's outcome")
    a = ap.parse_args()
    files = scenes(a.wild)
    if not files:
        sys.exit(f"no scenes found in {a.wild}/README.md")
    ok = checked = 0
    causes = collections.Counter()
    examples = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, f in enumerate(files):
            out = os.path.join(tmp, f"s{i}.tstats")
            search = search_folders(a.wild, f)
            cmd = [a.tstat, "render", f, "--out", out, "--width", "16", "--spp", "4",
                   "--bins", "8", "--threads", "2"] + search
            # `tstat check` must agree with the render about whether the scene works.
            c = subprocess.run([a.tstat, "check", f] + search, capture_output=True, text=True)
            checked += c.returncode == 0
            good, msg = run(cmd, a.timeout)
            # Scenes that leave parameters to the caller (`$spp` without a <default>,
            # as Mitsuba's docs build passes them): retry once with typical values.
            missing = re.findall(r"'\$(\w+)' has no <default", msg)
            if missing and missing[0] in PARAMETERS:
                extra = []
                for k, v in PARAMETERS.items():
                    extra += ["-D", f"{k}={v}"]
                good, msg = run(cmd + extra, a.timeout)
            rel = os.path.relpath(f, a.wild)
            if good:
                ok += 1
            else:
                key = normalise(msg)
                causes[key] += 1
                examples.setdefault(key, rel)
            if a.list:
                print(("ok   " if good else "FAIL ") + rel + ("" if good else "\n       " + msg))
            subprocess.run(["rm", "-rf", out])
    n = len(files)
    print(f"\n{ok} of {n} scenes load and render ({100.0 * ok / n:.1f}%); "
          f"`tstat check` says ok for {checked} (without scene parameters)")
    print("\nwhat blocks the rest (first error of each scene), most frequent first:")
    for key, count in causes.most_common():
        print(f"{count:4d}  {key}\n      e.g. {examples[key]}")


if __name__ == "__main__":
    main()
