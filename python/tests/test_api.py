"""The Python API against the command line: the same bits from the same arguments,
the command line's messages as exceptions, temporary bundles cleaned up, the GIL
released during a render, Ctrl-C stopping it cleanly, and a render's memory bounded
by its rows, not its volume."""

import glob
import hashlib
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import tstat

SMALL = dict(width=16, bins=40, bin_width_opl=0.25)
FLAGS = ["--width", "16", "--bins", "40", "--bin-width-opl", "0.25"]


def arrays(bundle_dir):
    """SHA-256 of each .npy of a bundle (the manifest records paths and times)."""
    out = {}
    for p in sorted(glob.glob(os.path.join(bundle_dir, "*.npy"))):
        with open(p, "rb") as f:
            out[os.path.basename(p)] = hashlib.sha256(f.read()).hexdigest()
    return out


def test_render_is_the_command_lines_render_bit_for_bit(cli, scene, tmp_path):
    b = tstat.render(scene("cbox.xml"), spp=8, seed=3, out=tmp_path / "py.tstats", progress=False, **SMALL)
    cli("render", scene("cbox.xml"), "--spp", 8, "--seed", 3, "--out", tmp_path / "cli.tstats", *FLAGS)
    got, want = arrays(b.path), arrays(tmp_path / "cli.tstats")
    assert set(want) >= {"x1.npy", "x2.npy", "x3.npy", "nonzero.npy", "albedo.npy"}
    assert got == want
    assert b.manifest["spp"] == 8 and b.manifest["seed"] == 3


def test_spectral_render_is_the_command_lines(cli, scene, tmp_path):
    b = tstat.render(scene("cbox_showcase.xml"), 4, seed=2, out=tmp_path / "py.tstats", progress=False,
                     mode="spectral", **SMALL)
    cli("render", scene("cbox_showcase.xml"), "--spp", 4, "--seed", 2, "--out", tmp_path / "cli.tstats",
        *FLAGS, "--mode", "spectral")
    assert arrays(b.path) == arrays(tmp_path / "cli.tstats")
    assert b.manifest["mode"] == "spectral"


def test_polarized_render_is_the_command_lines(cli, scene, tmp_path):
    b = tstat.render(scene("cbox_polarizers.xml"), 4, seed=2, out=tmp_path / "py.tstats", progress=False,
                     mode="mono_polarized", **SMALL)
    cli("render", scene("cbox_polarizers.xml"), "--spp", 4, "--seed", 2, "--out", tmp_path / "cli.tstats",
        *FLAGS, "--mode", "mono_polarized")
    assert arrays(b.path) == arrays(tmp_path / "cli.tstats")
    assert b.manifest["channels"] == ["S0", "S1", "S2", "S3"]
    assert b.shape[3] == 4 and b.mean().shape == b.shape
    assert (b.mean()[..., 1:] < 0).any()  # S1..S3 are signed


def test_spectral_polarized_render_is_the_command_lines(cli, scene, tmp_path):
    b = tstat.render(scene("cbox_polarizers.xml"), 4, seed=2, out=tmp_path / "py.tstats", progress=False,
                     mode="spectral_polarized", **SMALL)
    cli("render", scene("cbox_polarizers.xml"), "--spp", 4, "--seed", 2, "--out", tmp_path / "cli.tstats",
        *FLAGS, "--mode", "spectral_polarized")
    assert arrays(b.path) == arrays(tmp_path / "cli.tstats")
    assert b.manifest["channels"] == [f"S{j}.{c}" for c in "RGB" for j in range(4)]
    assert b.shape[3] == 12 and b.mean().shape == b.shape
    # The manifest's order is RGB-major: export's (H, W, T, 3, 4) is the reshape.
    cli("export", b.path, "--out", tmp_path / "v.npy")
    v = np.load(tmp_path / "v.npy")
    h, w, t, _ = b.shape
    assert v.shape == (h, w, t, 3, 4)
    assert np.array_equal(v, b.mean().reshape(h, w, t, 3, 4))


def test_adaptive_render_with_params_matches_the_command_line(cli, scene, tmp_path):
    opts = dict(SMALL, adaptive=True, pixel_sampling="independent", transform="yeo-johnson:0.5")
    b = tstat.render(scene("cbox.xml"), 16, seed=1, out=tmp_path / "py.tstats", progress=False, **opts)
    cli("render", scene("cbox.xml"), "--spp", 16, "--seed", 1, "--out", tmp_path / "cli.tstats", *FLAGS,
        "--adaptive", "--pixel-sampling", "independent", "--transform", "yeo-johnson:0.5")
    assert arrays(b.path) == arrays(tmp_path / "cli.tstats")
    n = b.pixel_spp()
    assert n.dtype == np.uint32 and n.shape == (16, 16)
    assert n.min() < n.max() and n.mean() == 16


def test_arrays_are_what_export_writes_and_spec5(cli, scene, tmp_path):
    b = tstat.render(scene("cbox.xml"), 8, seed=2, progress=False, **SMALL)
    cli("export", b.path, "--out", tmp_path / "noisy.npy", "--steady", tmp_path / "steady.npy")
    mean = b.mean()
    assert mean.dtype == np.float32 and mean.shape == b.shape == (16, 16, 40, 3)
    assert np.array_equal(mean, np.load(tmp_path / "noisy.npy"))
    assert np.array_equal(b.steady().astype(np.float32), np.load(tmp_path / "steady.npy"))
    # V = sigma2 / n from the raw sums (identity transform: z0 = 0).
    x1 = np.load(os.path.join(b.path, "x1.npy"))
    x2 = np.load(os.path.join(b.path, "x2.npy"))
    n = 8.0
    s2 = np.maximum(x2 / n - (x1 / n) ** 2, 0.0)
    want = s2 * n / (n - 1) / n
    v = b.variance()
    assert v.dtype == np.float32 and v.shape == mean.shape
    assert np.allclose(v, want, rtol=1e-5, atol=1e-12)
    assert (v > 0).sum() > 1000
    counts = b.counts()
    assert counts.dtype == np.uint32 and counts.shape == (16, 16, 40)
    assert np.array_equal(counts, np.load(os.path.join(b.path, "nonzero.npy")))
    g = b.gbuffers()
    assert set(g) == {"albedo", "normal", "depth", "emitter"}
    assert g["albedo"].shape == (16, 16, 3) and g["depth"].shape == (16, 16)


def test_denoise_is_the_command_lines_output_bit_for_bit(cli, scene, tmp_path):
    b = tstat.render(scene("cbox.xml"), 8, seed=4, progress=False, **SMALL)
    for method in ["tstat", "published"]:
        got = tstat.denoise(b, method=method)
        cli("denoise", b.path, "--method", method, "--out", tmp_path / f"{method}.npy")
        want = np.load(tmp_path / f"{method}.npy")
        assert got.dtype == np.float32 and got.shape == b.shape
        assert np.array_equal(got, want), method
    assert not np.array_equal(tstat.denoise(b, radius=2), tstat.denoise(b))


def test_merge_is_the_command_lines_merge(cli, scene, tmp_path):
    a = tstat.render(scene("cbox.xml"), 4, seed=1, progress=False, **SMALL)
    b = tstat.render(scene("cbox.xml"), 4, seed=2, progress=False, **SMALL)
    m = tstat.merge([a, b.path])
    cli("merge", a.path, b.path, "--out", tmp_path / "cli.tstats")
    assert m.manifest["spp"] == 8
    assert arrays(m.path) == arrays(tmp_path / "cli.tstats")
    with pytest.raises(TypeError):
        tstat.merge(a)


def test_nlos_reconstruct_is_the_command_lines(cli, scene, tmp_path):
    cap = tstat.render(scene("nlos_T.xml"), 4, progress=False, width=8, bins=64)
    grid = dict(volume=(-0.5, 0.5, -0.5, 0.5, 0.6, 1.4), voxels=(6, 6, 5))
    for method, extra in [("bp", []), ("fbp", ["--wl-mean", "0.25"])]:
        opts = {"wl_mean": 0.25} if extra else {}
        got = tstat.nlos.reconstruct(cap, method, **grid, **opts)
        cli("nlos", "reconstruct", cap.path, "--method", method, "--volume", "-0.5,0.5,-0.5,0.5,0.6,1.4",
            "--voxels", "6,6,5", "--out", tmp_path / f"{method}.npy", *extra)
        assert got.shape == (6, 6, 5)
        assert np.array_equal(got, np.load(tmp_path / f"{method}.npy")), method


def test_report_convergence_returns_the_command_lines_table(cli, scene, tmp_path):
    rows = tstat.report.convergence(scene("cbox.xml"), [4, 8], out=tmp_path / "r", reference_spp=32,
                                    no_adaptive=True, **SMALL)
    assert {r["spp"] for r in rows} == {4, 8}
    assert all(isinstance(r["spp"], int) for r in rows)
    cli("report", "convergence", scene("cbox.xml"), "--spp", "4,8", "--out", tmp_path / "c", "--reference-spp", 32,
        "--no-adaptive", *FLAGS)
    with open(tmp_path / "c" / "results.csv") as f:
        import csv
        want = list(csv.DictReader(f))
    assert len(rows) == len(want) > 4
    # The same renders and errors; only the timings differ.
    for got, w in zip(rows, want):
        for k, v in w.items():
            if not (k.endswith("_s") or k.startswith("speedup") or k.startswith("g_evaluations")):
                assert str(got[k]) == v or float(got[k]) == float(v), (k, got[k], v)


def test_bad_input_raises_the_command_lines_message(scene, tmp_path):
    with pytest.raises(tstat.TstatError, match=r"--spp 1: must be at least 2"):
        tstat.render(scene("cbox.xml"), 1, progress=False)
    with pytest.raises(TypeError, match="spp must be an int"):
        tstat.render(scene("cbox.xml"), 4.0, progress=False)
    with pytest.raises(TypeError):
        tstat.render(scene("cbox.xml"), True, progress=False)
    with pytest.raises(tstat.TstatError, match="unexpected argument '--colour'"):
        tstat.render(scene("cbox.xml"), 4, colour=3, progress=False)
    with pytest.raises(tstat.TstatError, match="--bins 0: must be at least 1"):
        tstat.render(scene("cbox.xml"), 4, bins=0, progress=False)
    with pytest.raises(tstat.TstatError, match="no_such.xml"):
        tstat.render(tmp_path / "no_such.xml", 4, progress=False)
    with pytest.raises(tstat.TstatError, match="no_such.tstats"):
        tstat.load(tmp_path / "no_such.tstats")
    (tmp_path / "fake.tstats").mkdir()
    (tmp_path / "fake.tstats" / "manifest.json").write_text("{nan}")
    with pytest.raises(tstat.TstatError, match="manifest.json"):
        tstat.load(tmp_path / "fake.tstats")
    # Nothing the user had is replaced without force.
    out = tmp_path / "keep.tstats"
    out.mkdir()
    with pytest.raises(tstat.TstatError, match="exists"):
        tstat.render(scene("cbox.xml"), 4, out=out, progress=False, **SMALL)
    assert os.listdir(out) == []
    with pytest.raises(tstat.TstatError):
        tstat.nlos.reconstruct(tmp_path / "no.hdf5", "bp", (0, 1, 0, 1, 0, 1), "2,2")


def test_temporary_bundles_go_with_their_object_and_save_keeps_them(scene, tmp_path):
    b = tstat.render(scene("cbox.xml"), 4, progress=False, **SMALL)
    assert b.temporary
    folder = os.path.dirname(b.path)
    kept = b.save(tmp_path / "kept.tstats")
    assert not kept.temporary
    assert np.array_equal(kept.mean(), b.mean())
    with pytest.raises(tstat.TstatError, match="exists"):
        b.save(tmp_path / "kept.tstats")
    b.save(tmp_path / "kept.tstats", force=True)
    del b
    assert not os.path.exists(folder)
    assert tstat.load(tmp_path / "kept.tstats").manifest["spp"] == 4


def test_progress_reaches_the_callback_and_the_threads_change_no_bit(scene):
    seen = []
    one = tstat.render(scene("cbox.xml"), 8, threads=1, adaptive=True, progress=lambda *a: seen.append(a), **SMALL)
    two = tstat.render(scene("cbox.xml"), 8, threads=2, adaptive=True, progress=False, **SMALL)
    assert arrays(one.path) == arrays(two.path)
    stages = {s for s, *_ in seen}
    assert stages == {"pilot", "render"}
    last = [a for a in seen if a[0] == "render"][-1]
    assert last[1] == last[2] == one.manifest["spp"] * 16 * 16


def test_the_gil_is_released_during_a_render(scene):
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.001)

    t = threading.Thread(target=tick)
    t.start()
    start = time.perf_counter()
    tstat.render(scene("cbox.xml"), 512, width=48, bins=100, bin_width_opl=0.1, threads=1, progress=False)
    seconds = time.perf_counter() - start
    stop.set()
    t.join()
    assert seconds > 0.3, "the render should take long enough to measure"
    # A thread starved of the GIL would tick a handful of times; a free one ~1000/s.
    assert len(ticks) > 50 * seconds, (len(ticks), seconds)


INTERRUPTED = """
import _thread, os, signal, sys, threading, tstat
# Python's own Ctrl-C handler, even when the test runs with SIGINT ignored (a
# background job of a non-interactive shell inherits SIG_IGN).
signal.signal(signal.SIGINT, signal.default_int_handler)
out = sys.argv[2]
threading.Timer(0.5, _thread.interrupt_main).start()
try:
    tstat.render(sys.argv[1], 4096, out=out, width=64, bins=100, threads=1, progress=False)
    print("finished")
except KeyboardInterrupt:
    print("interrupted", os.path.exists(out), sorted(os.listdir(os.path.dirname(out))))
"""


def test_ctrl_c_stops_a_render_cleanly(scene, tmp_path):
    out = tmp_path / "x" / "b.tstats"
    out.parent.mkdir()
    r = subprocess.run([sys.executable, "-c", INTERRUPTED, scene("cbox.xml"), str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["interrupted", "False", "[]"], r.stdout


MEMORY = """
import resource, sys, tstat
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
b = tstat.render(sys.argv[1], 4, width=128, bins=600, threads=1, progress=False)
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(after - before)
"""


def test_a_render_streams_its_volume_instead_of_holding_it(scene):
    r = subprocess.run([sys.executable, "-c", MEMORY, scene("cbox.xml")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    grown_kb = int(r.stdout.split()[-1])
    # The sums alone are 128 x 128 x 600 x 3 x 8 bytes x 3 arrays = 708 MB; a row
    # scratch is 128 x 600 x 3 x 8 x 4 = 7.4 MB.
    assert grown_kb * 1024 < 100e6, f"peak memory grew by {grown_kb / 1024:.0f} MiB"


def test_arrays_out_are_export_published_and_arrays_in_denoise_as_the_bundle(cli, scene, tmp_path):
    b = tstat.render(scene("cbox.xml"), 16, seed=5, transform="yeo-johnson:0.5", pixel_sampling="independent",
                     progress=False, **SMALL)
    cli("export", b.path, "--published", tmp_path / "arr")
    arrays = b.published_arrays()
    for name, a in arrays.items():
        assert a.dtype == np.float32
        assert np.array_equal(a, np.load(tmp_path / "arr" / f"{name}.npy")), name
    g = b.gbuffers()
    cli("denoise", b.path, "--out", tmp_path / "tstat.npy")
    cli("denoise", b.path, "--method", "published", "--out", tmp_path / "published.npy")
    args = (arrays["noisy"], arrays["estimands"], arrays["estimands_variance"], 16, arrays["albedo"],
            arrays["normals"])
    # With tstat's extras the filter has all a bundle gives it.
    full = tstat.denoise_arrays(*args, depth=g["depth"], emitter=g["emitter"], bin_width_opl=0.25)
    assert np.array_equal(full, np.load(tmp_path / "tstat.npy"))
    # The published pipeline's five arrays: its filter needs nothing more.
    published = tstat.denoise_arrays(*args, method="published")
    assert np.array_equal(published, np.load(tmp_path / "published.npy"))
    # f64 inputs are read as f32.
    as64 = tstat.denoise_arrays(*[a.astype(np.float64) if isinstance(a, np.ndarray) else a for a in args],
                                method="published")
    assert np.array_equal(as64, published)


def test_bad_arrays_raise_the_command_lines_message(scene):
    b = tstat.render(scene("cbox.xml"), 8, transform="yeo-johnson:0.5", progress=False, **SMALL)
    a = b.published_arrays()
    args = lambda **kw: {**dict(noisy=a["noisy"], mean=a["estimands"], variance=a["estimands_variance"], spp=8,
                                albedo=a["albedo"], normal=a["normals"]), **kw}
    bad = a["estimands"].copy()
    bad[1, 2, 3, 0] = np.nan
    with pytest.raises(tstat.TstatError, match=r"estimands.npy.*NaN"):
        tstat.denoise_arrays(**args(mean=bad))
    neg = a["estimands_variance"].copy()
    neg[0, 0, 0, 0] = -1.0
    with pytest.raises(tstat.TstatError, match="at least 0"):
        tstat.denoise_arrays(**args(variance=neg))
    with pytest.raises(tstat.TstatError, match=r"albedo.npy: shape \[16, 15, 3\]"):
        tstat.denoise_arrays(**args(albedo=a["albedo"][:, :15]))
    with pytest.raises(tstat.TstatError, match="normals.npy"):
        tstat.denoise_arrays(**args(normal=np.zeros((16, 16, 3), dtype=np.int64)))
    with pytest.raises(tstat.TstatError, match="--spp 1"):
        tstat.denoise_arrays(**args(spp=1))
    with pytest.raises(TypeError):
        tstat.denoise_arrays(**args(spp="8"))
