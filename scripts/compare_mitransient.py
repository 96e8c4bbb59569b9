#!/usr/bin/env python3
"""Render time of tstat against mitransient, side by side on the same scene files.

For each scene, renders it in turn with the tstat release binary (`tstat render`,
statistics on) and with mitransient (Mitsuba 3, no statistics), N times alternating,
and prints a Markdown table of the render times: median and range of each, and the
ratio of the medians. Both get the same XML file unchanged, the same film, time bins,
spp and thread count:

- the film size and bins go in as the scene's `<default>`s `res` and `temporal_bins`
  (`tstat render -D`, `mitsuba.load_file(..., res=, temporal_bins=)`); a scene that does
  not declare them is rendered at its own film size by both;
- spp: `tstat render --spp`, `integrator.render(scene, spp=)`;
- threads: `tstat render --threads`, `drjit.set_thread_count`.

Times. tstat: `render_seconds` from the bundle's manifest (the render loop: scene load,
BVH build and writing the bundle excluded).
mitransient: each repetition is a fresh Python process; the render time runs from
`integrator.render` until the steady and transient images are evaluated (Dr.Jit
tracing, kernel compilation or its cache look-up, and the kernel itself); import and
`load_file` are timed separately. For both, the whole process's wall and CPU seconds
(user + system, all threads: less sensitive to other work on a shared machine) are
reported in a second table. A warm-up run of each renderer per scene (untimed in
the table, reported beside it) fills Dr.Jit's on-disk kernel cache and the page cache.

Rates. tstat's M rays/s and M paths/s are the ones `tstat render` prints (rays: the
closest-hit and shadow rays traced, over the render seconds). mitransient does not
report how many rays it traces: "-".

Instructions (`--instructions`, slow: off by default). Each scene is rendered once more
by tstat under valgrind's callgrind at a small film (`--instr-res`, `--instr-spp`, the
same bins, one thread), collecting only inside `tstat::render::render_into*` (the render
loop; `--toggle-collect`). Its instruction count over the exact numbers of paths and
rays that render prints (`(N paths, M rays)`) gives instructions per path and per ray.
mitransient is not measured: no hardware counters (`perf stat`) on this VM, and
callgrind does not measure Dr.Jit's LLVM-JIT kernels.

Not part of CI. Needs Python >= 3.11 and the Rust toolchain; mitransient and valgrind
(for `--instructions`) are optional:

    pip install mitsuba mitransient          # mitransient 1.3.1 / Mitsuba 3.9.1 measured
    apt-get install -y libllvm19             # Dr.Jit's LLVM backend
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so  # else searched

    python3 scripts/compare_mitransient.py                 # the six default scenes
    python3 scripts/compare_mitransient.py scenes/cbox.xml --spp 64 --repeats 5
    python3 scripts/compare_mitransient.py scenes/cbox.xml --instructions  # + callgrind

Without mitransient (or without a working LLVM) it says so and prints tstat's times;
without valgrind, `--instructions` says so and skips its table.
The scene `dense` is the displaced sphere of >= 1M triangles, generated on first use by
`cargo run --release --example dense_scene` into target/bench-scenes/ (not committed).
"""

from __future__ import annotations

import argparse
import glob
import importlib.util
import json
import os
import platform
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SCENES = ["scenes/cbox.xml", "scenes/cbox_spheres.xml", "scenes/bunny.xml", "dense",
                  "scenes/cbox_fog.xml", "scenes/cbox_materials.xml"]
# Prefixes the worker's one-line JSON result on stdout.
RESULT = "compare_mitransient result: "
# `tstat render`'s last line on stdout: "rendered X in S s: P M paths/s, R M rays/s; ...".
RATES = re.compile(r"in ([0-9.]+) s: ([0-9.]+) M paths/s, ([0-9.]+) M rays/s")
# Callgrind collects only inside the render loop (generic over its row sink: wildcard).
TOGGLE = "tstat::render::render_into*"
# Runs of the small render without valgrind whose printed rates bound rays per path.
LLVM_CANDIDATES = [
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/llvm-19/lib/libLLVM.so.1",
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/llvm-*/lib/libLLVM.so*",
    "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
]


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------------------
# mitransient worker: one render in a fresh process, result as one JSON line on stdout.
# --------------------------------------------------------------------------------------


def worker(a: argparse.Namespace) -> None:
    t0 = time.perf_counter()
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(a.variant)
    import mitransient  # noqa: F401  (registers transient_path, transient_hdr_film)
    import numpy as np

    dr.set_thread_count(a.threads)
    t1 = time.perf_counter()
    params = json.loads(a.params)
    scene = mi.load_file(a.scene, **params)
    t2 = time.perf_counter()
    steady, transient = scene.integrator().render(scene, spp=a.spp, seed=a.seed)
    dr.eval(steady, transient)
    dr.sync_thread()
    t3 = time.perf_counter()
    shape = list(np.array(transient).shape)
    print(
        RESULT
        + json.dumps(
            {
                "import_s": t1 - t0,
                "load_s": t2 - t1,
                "render_s": t3 - t2,
                "shape": shape,
                "threads": dr.thread_count(),
                "versions": {
                    "mitsuba": mi.__version__,
                    "mitransient": mitransient.__version__,
                    "drjit": dr.__version__,
                },
            }
        )
    )


# --------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------


@dataclass
class Times:
    render: list[float] = field(default_factory=list)
    other: list[float] = field(default_factory=list)  # tstat: process wall; mi: load
    cpu: list[float] = field(default_factory=list)  # whole process, user + system
    mrays: list[float] = field(default_factory=list)  # tstat: printed M rays/s
    mpaths: list[float] = field(default_factory=list)  # tstat: printed M paths/s
    warmup: float | None = None
    film: str = "?"
    error: str | None = None


def declared_defaults(xml: Path) -> set[str]:
    try:
        root = ET.parse(xml).getroot()
    except (ET.ParseError, OSError) as e:
        sys.exit(f"error: {xml}: {e}")
    return {d.get("name") for d in root.findall("default")}


def find_llvm() -> str | None:
    for pattern in LLVM_CANDIDATES:
        for path in sorted(glob.glob(pattern), reverse=True):
            if os.path.isfile(path):
                return path
    return None


def mitransient_status(variant: str) -> tuple[bool, str]:
    """Whether mitransient can run here, and why not (or the LLVM library used)."""
    missing = [m for m in ("mitsuba", "drjit", "mitransient") if importlib.util.find_spec(m) is None]
    if missing:
        return False, (
            f"mitransient is not installed (missing Python modules: {', '.join(missing)}); "
            "install it with `pip install mitsuba mitransient` (and `apt-get install -y "
            "libllvm19` for the LLVM backend) to compare. Timing tstat alone."
        )
    if variant.startswith("llvm") and not os.environ.get("DRJIT_LIBLLVM_PATH"):
        path = find_llvm()
        if path is None:
            return False, (
                "mitransient is installed but no libLLVM was found for Dr.Jit's LLVM backend: "
                "`apt-get install -y libllvm19` or set DRJIT_LIBLLVM_PATH. Timing tstat alone."
            )
        os.environ["DRJIT_LIBLLVM_PATH"] = path
    return True, f"DRJIT_LIBLLVM_PATH={os.environ.get('DRJIT_LIBLLVM_PATH', '')}"


def run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, text=True, capture_output=True, **kw)


def run_cpu(cmd: list[str]) -> tuple[subprocess.CompletedProcess, float]:
    """Runs cmd; also returns its CPU seconds (user + system, all threads)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = run(cmd)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def build_tstat(a: argparse.Namespace) -> Path:
    if a.tstat:
        return Path(a.tstat)
    log("building tstat (cargo build --release) ...")
    r = subprocess.run(["cargo", "build", "--release", "--quiet", "--bin", "tstat"], cwd=ROOT)
    if r.returncode != 0:
        sys.exit("error: cargo build --release failed")
    return ROOT / "target" / "release" / "tstat"


def dense_scene(a: argparse.Namespace) -> Path:
    out = Path(a.dense_dir)
    xml = out / "dense_sphere.xml"
    stamp = out / "triangles_requested"
    if xml.exists() and stamp.exists() and stamp.read_text().strip() == str(a.dense_triangles):
        return xml
    log(f"generating the dense scene (>= {a.dense_triangles} triangles) in {out} ...")
    r = subprocess.run(
        ["cargo", "run", "--release", "--quiet", "--example", "dense_scene", "--",
         str(out), str(a.dense_triangles)],
        cwd=ROOT,
    )
    if r.returncode != 0:
        sys.exit("error: generating the dense scene failed")
    stamp.write_text(f"{a.dense_triangles}\n")
    return xml


def rates(stdout: str) -> tuple[float, float]:
    """M paths/s and M rays/s as `tstat render` prints them."""
    found = RATES.findall(stdout)
    if not found:
        raise RuntimeError(f"no rates in tstat's output: {stdout.strip()!r}")
    return float(found[-1][1]), float(found[-1][2])


def time_tstat(
    tstat: Path, xml: Path, params: dict, a: argparse.Namespace, seed: int
) -> tuple[float, float, float, str, float, float]:
    """Render seconds (manifest), process wall and CPU seconds, film, M paths/s, M rays/s."""
    with tempfile.TemporaryDirectory(prefix="tstat-compare-", dir=a.work_dir) as tmp:
        out = Path(tmp) / "run.tstats"
        cmd = [str(tstat), "render", str(xml), "--out", str(out), "--spp", str(a.spp),
               "--threads", str(a.threads), "--seed", str(seed)]
        for k, v in params.items():
            cmd += ["-D", f"{k}={v}"]
        t = time.perf_counter()
        r, cpu = run_cpu(cmd)
        wall = time.perf_counter() - t
        if r.returncode != 0:
            raise RuntimeError(f"tstat render failed: {r.stderr.strip()}")
        m = json.loads((out / "manifest.json").read_text())
        film = f"{m['width']}x{m['height']}x{m['bins']}"
        mpaths, mrays = rates(r.stdout)
        return m["render_seconds"], wall, cpu, film, mpaths, mrays


@dataclass
class Instr:
    film: str = "?"
    spp: int = 0
    ir: int = 0  # instructions collected in the render loop
    paths: int = 0  # as the render prints them: exact
    rays: int = 0
    error: str | None = None


COUNTS = re.compile(r"\(([0-9]+) paths, ([0-9]+) rays\)")


def count_instructions(tstat: Path, xml: Path, a: argparse.Namespace) -> Instr:
    """One small render under callgrind (render loop only, one thread), with the exact
    path and ray counts it prints."""
    declared = declared_defaults(xml)
    res = ["-D", f"res={a.instr_res}"] if "res" in declared else ["--width", str(a.instr_res)]
    bins = ["-D", f"temporal_bins={a.bins}"] if "temporal_bins" in declared else []
    t = Instr(spp=a.instr_spp)
    with tempfile.TemporaryDirectory(prefix="tstat-compare-", dir=a.work_dir) as tmp:
        out = Path(tmp) / "run.tstats"
        cg = Path(tmp) / "callgrind.out"
        render = [str(tstat), "render", str(xml), "--out", str(out), "--force", "--spp",
                  str(a.instr_spp), "--seed", str(a.seed), *res, *bins]
        r = run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={cg}",
                 f"--toggle-collect={TOGGLE}", *render, "--threads", "1"])
        if r.returncode != 0 or not cg.exists():
            tail = (r.stderr.strip().splitlines() or ["(no output)"])[-1]
            raise RuntimeError(f"tstat render under callgrind failed (exit {r.returncode}): {tail}")
        totals = {}
        for line in cg.read_text(errors="replace").splitlines():
            if line.startswith(("summary:", "totals:")):
                key, value = line.split(":", 1)
                totals[key] = int(value.split()[0])
        t.ir = totals.get("totals", totals.get("summary", 0))
        if t.ir <= 0:
            raise RuntimeError(f"callgrind collected no instructions in {TOGGLE} (symbol renamed?)")
        m = json.loads((out / "manifest.json").read_text())
        t.film = f"{m['width']}x{m['height']}x{m['bins']}"
        counts = COUNTS.findall(r.stdout)
        if not counts:
            raise RuntimeError(f"no path and ray counts in tstat's output: {r.stdout.strip()!r}")
        t.paths, t.rays = int(counts[-1][0]), int(counts[-1][1])
    return t


def time_mitransient(xml: Path, params: dict, a: argparse.Namespace, seed: int) -> dict:
    cmd = [sys.executable, __file__, "--worker", "--variant", a.variant, "--threads",
           str(a.threads), "--spp", str(a.spp), "--seed", str(seed), "--params",
           json.dumps(params), str(xml)]
    r, cpu = run_cpu(cmd)
    # Mitsuba logs to stdout too (with colour codes): find the result by its marker.
    found = [l.split(RESULT, 1)[1] for l in r.stdout.splitlines() if RESULT in l]
    if r.returncode != 0 or not found:
        tail = (r.stderr.strip().splitlines() or r.stdout.strip().splitlines() or ["(no output)"])[-1]
        raise RuntimeError(f"mitransient failed (exit {r.returncode}): {tail}")
    return json.loads(found[-1]) | {"cpu_s": cpu}


def secs(x: float) -> str:
    return f"{x:.2f}" if x >= 1 else f"{x:.3f}"


def fmt(xs: list[float]) -> str:
    if not xs:
        return "-"
    return f"{secs(statistics.median(xs))} ({secs(min(xs))}-{secs(max(xs))})"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenes", nargs="*", help="scene XML files, or `dense` (default: cbox, cbox_spheres, bunny, dense, cbox_fog, cbox_materials)")
    p.add_argument("--res", type=int, default=128, help="film width and height, as the scene default `res` (128)")
    p.add_argument("--bins", type=int, default=300, help="time bins, as the scene default `temporal_bins` (300)")
    p.add_argument("--spp", type=int, default=512, help="samples per pixel (512)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs of each renderer per scene (3)")
    p.add_argument("--threads", type=int, default=2, help="threads for both renderers (2)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first run (+1 per run)")
    p.add_argument("--no-warmup", action="store_true", help="skip the untimed first run of each renderer")
    p.add_argument("--variant", default="llvm_ad_rgb", help="Mitsuba variant (llvm_ad_rgb)")
    p.add_argument("--tstat", help="tstat binary (default: build target/release/tstat)")
    p.add_argument("--dense-dir", default=str(ROOT / "target" / "bench-scenes"), help="where the dense scene is generated")
    p.add_argument("--dense-triangles", type=int, default=1_000_000, help="minimum triangles of the dense scene")
    p.add_argument("--work-dir", default=None, help="where the temporary tstat bundles go (default: system temp)")
    p.add_argument("--no-mitransient", action="store_true", help="time tstat only")
    p.add_argument("--instructions", action="store_true", help="also count tstat's instructions per path under valgrind's callgrind (slow)")
    p.add_argument("--instr-res", type=int, default=32, help="film width and height of the callgrind render, as `res` (32)")
    p.add_argument("--instr-spp", type=int, default=128, help="samples per pixel of the callgrind render (128: the per-pixel costs amortised as at 512 spp)")
    # Internal: one mitransient render in this process.
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--params", default="{}", help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.worker:
        a.scene = a.scenes[0]
        worker(a)
        return
    for name in ("res", "bins", "spp", "repeats", "threads", "dense_triangles", "instr_res", "instr_spp"):
        if getattr(a, name) < (2 if name in ("spp", "instr_spp") else 1):
            p.error(f"--{name.replace('_', '-')} {getattr(a, name)}: too small")

    with_mi, why = (False, "mitransient skipped (--no-mitransient)") if a.no_mitransient else mitransient_status(a.variant)
    log(why if not with_mi else f"mitransient: {a.variant}, {why}")
    tstat = build_tstat(a)
    scenes: list[tuple[str, Path]] = []
    for s in a.scenes or DEFAULT_SCENES:
        xml = dense_scene(a) if s == "dense" else Path(s).resolve() if Path(s).exists() else ROOT / s
        if not xml.exists():
            sys.exit(f"error: scene {s} not found")
        scenes.append(("dense" if s == "dense" else xml.stem, xml))

    load_before = os.getloadavg()[0]
    results: dict[str, tuple[Times, Times]] = {}
    versions: dict = {}
    notes: list[str] = []
    for name, xml in scenes:
        declared = declared_defaults(xml)
        params = {k: v for k, v in (("res", a.res), ("temporal_bins", a.bins)) if k in declared}
        if len(params) < 2:
            notes.append(f"{name}: declares no `res`/`temporal_bins` default; rendered at its own film size")
        ts, mt = Times(), Times()
        results[name] = (ts, mt)
        runs = ([-1] if not a.no_warmup else []) + list(range(a.repeats))
        for rep in runs:
            seed = a.seed + max(rep, 0)
            label = "warm-up" if rep < 0 else f"run {rep + 1}/{a.repeats}"
            if ts.error is None:
                try:
                    render_s, wall, cpu, ts.film, mpaths, mrays = time_tstat(tstat, xml, params, a, seed)
                    log(f"{name} {label}: tstat {render_s:.2f} s render, {wall:.2f} s process")
                    if rep < 0:
                        ts.warmup = render_s
                    else:
                        ts.render.append(render_s)
                        ts.other.append(wall)
                        ts.cpu.append(cpu)
                        ts.mpaths.append(mpaths)
                        ts.mrays.append(mrays)
                except RuntimeError as e:
                    ts.error = str(e)
                    log(f"{name}: {e}")
            if with_mi and mt.error is None:
                try:
                    r = time_mitransient(xml, params, a, seed)
                    versions = r["versions"]
                    h, w, t = r["shape"][:3]
                    mt.film = f"{w}x{h}x{t}"
                    log(f"{name} {label}: mitransient {r['render_s']:.2f} s render, "
                        f"{r['load_s']:.2f} s load, {r['import_s']:.2f} s import")
                    if rep < 0:
                        mt.warmup = r["render_s"]
                    else:
                        mt.render.append(r["render_s"])
                        mt.other.append(r["load_s"])
                        mt.cpu.append(r["cpu_s"])
                except RuntimeError as e:
                    mt.error = str(e)
                    log(f"{name}: {e}")
        if with_mi and mt.error is None and ts.error is None and mt.film != ts.film:
            notes.append(f"{name}: films differ, tstat {ts.film}, mitransient {mt.film}")

    instr: dict[str, Instr] = {}
    valgrind = shutil.which("valgrind") if a.instructions else None
    if a.instructions and valgrind is None:
        log("valgrind not found: no instruction counts (apt-get install -y valgrind)")
    for name, xml in scenes if valgrind else []:
        log(f"{name}: tstat under callgrind ({a.instr_res} px, {a.instr_spp} spp, 1 thread) ...")
        try:
            instr[name] = count_instructions(tstat, xml, a)
            log(f"{name}: {instr[name].ir:,} instructions in the render loop, {instr[name].paths:,} paths")
        except RuntimeError as e:
            instr[name] = Instr(error=str(e))
            log(f"{name}: {e}")

    # ---- report ----
    print(f"Render times, {time.strftime('%Y-%m-%d')}, {cpu_model()}, {os.cpu_count()} cores, "
          f"{a.threads} threads each; {a.repeats} run(s), median (min-max) in seconds.")
    print(f"Load average (1 min; other work on the machine): {load_before:.1f} before, "
          f"{os.getloadavg()[0]:.1f} after.")
    tv = run([str(tstat), "--version"]).stdout.strip() or "tstat"
    mv = (f"mitransient {versions['mitransient']} / Mitsuba {versions['mitsuba']} / "
          f"Dr.Jit {versions['drjit']} ({a.variant})") if versions else "mitransient not run"
    print(f"{tv} (statistics on); {mv}.\n")
    print("| scene | film | spp | tstat s | mitransient s | tstat / mitransient "
          "| tstat M rays/s | mitransient M rays/s | tstat M paths/s |")
    print("|---|---|---:|---|---|---:|---:|---:|---:|")
    for name, (ts, mt) in results.items():
        ratio = (f"{statistics.median(ts.render) / statistics.median(mt.render):.2f}"
                 if ts.render and mt.render else "-")
        med = lambda xs: f"{statistics.median(xs):.2f}" if xs else "-"  # noqa: E731
        print(f"| {name} | {ts.film} | {a.spp} | {ts.error and 'failed' or fmt(ts.render)} | "
              f"{mt.error and 'failed' or fmt(mt.render)} | {ratio} | {med(ts.mrays)} | - "
              f"| {med(ts.mpaths)} |")
    print()
    print("M rays/s and M paths/s: medians of the rates `tstat render` prints (rays: "
          "closest-hit and shadow rays traced, over the render seconds). mitransient does "
          "not report how many rays it traces, hence \"-\".\n")
    print("Whole processes (tstat: load, render, write the bundle; mitransient: import, "
          "load_file, render); CPU seconds are user + system over all threads, less "
          "sensitive to other work on the machine than wall seconds.\n")
    print("| scene | tstat warm-up render s | tstat wall s | tstat CPU s "
          "| mitransient warm-up render s | mitransient load_file s | mitransient CPU s "
          "| CPU tstat / mitransient |")
    print("|---|---:|---|---|---:|---|---|---:|")
    for name, (ts, mt) in results.items():
        w = lambda x: "-" if x is None else secs(x)  # noqa: E731
        cpu_ratio = (f"{statistics.median(ts.cpu) / statistics.median(mt.cpu):.2f}"
                     if ts.cpu and mt.cpu else "-")
        print(f"| {name} | {w(ts.warmup)} | {fmt(ts.other)} | {fmt(ts.cpu)} | {w(mt.warmup)} "
              f"| {fmt(mt.other)} | {fmt(mt.cpu)} | {cpu_ratio} |")
    if a.instructions:
        print()
        if valgrind is None:
            print("Instructions: valgrind not found (`apt-get install -y valgrind`); skipped.")
        else:
            print(f"Instructions (valgrind callgrind, Ir collected only in `{TOGGLE}`: the "
                  "render loop, without scene load, BVH build or writing the bundle), one "
                  f"tstat render per scene at {a.instr_spp} spp, 1 thread; paths and rays "
                  "as that render counts them (closest-hit and shadow rays). callgrind counts "
                  "a `rep stosb` byte by byte: the per-pixel reset of the sums (8 bytes x 10 "
                  "per bin) adds about 80 x bins / spp to the instructions per path that the "
                  "CPU does not execute.\n")
            print("| scene | film | spp | instructions per path | rays per path "
                  "| instructions per ray |")
            print("|---|---|---:|---:|---:|---:|")
            for name, t in instr.items():
                if t.error:
                    print(f"| {name} | - | - | failed | - | - |")
                    continue
                print(f"| {name} | {t.film} | {t.spp} | {t.ir / t.paths:,.0f} | "
                      f"{t.rays / t.paths:.2f} | {t.ir / t.rays:,.0f} |")
            print("\nmitransient: no column. Hardware counters (`perf stat`) are unavailable on "
                  "this VM, and callgrind does not measure Dr.Jit's LLVM-JIT kernels.")
            for name, t in instr.items():
                if t.error:
                    notes.append(f"{name}: instructions: {t.error}")
    if not with_mi:
        print(f"\n{why}")
    for name, (ts, mt) in results.items():
        for who, t in (("tstat", ts), ("mitransient", mt)):
            if t.error:
                notes.append(f"{name}: {who}: {t.error}")
    for n in notes:
        print(f"\nNote: {n}")


if __name__ == "__main__":
    main()
