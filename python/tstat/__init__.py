"""tstat from Python: render a scene as a time-resolved volume L(y, x, t) with per-voxel
sample statistics, denoise it, merge renders, reconstruct NLOS captures, and measure
error against time, with NumPy arrays in and out.

The package is the command-line program's library (a Rust extension): the same
renders, bit for bit, the same checks and the same messages. Every keyword option is
the command line's flag of that name (``bin_width_opl=0.01`` is ``--bin-width-opl
0.01``; ``True`` is a bare flag). Rust works with the GIL released.

    import tstat
    b = tstat.render("scenes/cbox.xml", spp=16, width=64, bins=150)
    video = b.mean()                      # (H, W, T, 3) float32
    clean = tstat.denoise(b)              # the array `tstat denoise` writes
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from typing import Any, Callable, Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _tstat
from ._flags import defines, flags, whole
from ._tstat import TstatError, __version__

PathLike = Union[str, "os.PathLike[str]"]
#: ``progress(stage, done, total, status)``: stage is "pilot" or "render", done and
#: total count paths, status is the running error estimate of adaptive renders.
ProgressCallback = Callable[[str, int, int, str], None]

__all__ = [
    "Bundle",
    "TstatError",
    "denoise",
    "denoise_arrays",
    "load",
    "merge",
    "nlos",
    "render",
    "report",
    "run",
    "__version__",
]


class Bundle:
    """A statistics bundle (``NAME.tstats``): the sums X1, X2, X3 of each voxel's path
    samples, the per-voxel counts, the G-buffers and the manifest. Arrays are read from
    disk when asked; each call returns a new array.

    A bundle rendered or merged without ``out`` lives in a temporary folder that is
    removed when the object is garbage collected; :meth:`save` keeps it.
    """

    def __init__(self, native: "_tstat.Bundle") -> None:
        self._native = native
        self._manifest: Optional[Dict[str, Any]] = None

    @property
    def path(self) -> str:
        """The bundle's folder."""
        return os.fspath(self._native.path)

    @property
    def temporary(self) -> bool:
        """True when the folder is removed with this object (see :meth:`save`)."""
        return self._native.temporary

    @property
    def manifest(self) -> Dict[str, Any]:
        """``manifest.json`` as a dict (film, time axis, spp, seed, transform, ...)."""
        if self._manifest is None:
            self._manifest = json.loads(self._native.manifest_json())
        return self._manifest

    @property
    def shape(self) -> Tuple[int, int, int, int]:
        """(H, W, T, C) of the volumes: C is 3 (R, G, B: modes rgb and spectral), 1 (Y:
        mono), 4 (the Stokes components S0..S3: mono_polarized) or 12 (S0..S3 of each
        sRGB channel, RGB-major: spectral_polarized; ``.reshape(h, w, t, 3, 4)`` gives
        colour x component, the shape ``tstat export --out`` writes);
        ``manifest["channels"]`` names them."""
        m = self.manifest
        return (m["height"], m["width"], m["bins"], len(m["channels"]))

    def mean(self) -> np.ndarray:
        """The noisy mean volume S / n, float32 (H, W, T, C): what ``tstat export
        --out`` writes (each pixel divided by its own count in adaptive bundles)."""
        return self._native.mean()

    def estimates(self) -> Tuple[np.ndarray, np.ndarray]:
        """``(theta, V)``, float32 (H, W, T, C): SPEC 5's skewness-corrected mean and
        the variance of the estimate, in the domain of the bundle's transform (linear
        radiance for the identity; the published pipeline's estimand and
        estimand_variance for ``transform="yeo-johnson:0.5"``)."""
        return self._native.estimates()

    def variance(self) -> np.ndarray:
        """The variance of each voxel's mean, V = sigma2 / n, float32 (H, W, T, C), in
        the transform's domain (unbiased sigma2, each pixel's own n)."""
        return self._native.estimates()[1]

    def counts(self) -> np.ndarray:
        """Paths that deposited something in each voxel, uint32 (H, W, T)."""
        return self._native.counts()

    def pixel_spp(self) -> np.ndarray:
        """Samples of each pixel, uint32 (H, W) (all ``spp`` unless adaptive)."""
        return self._native.pixel_spp()

    def gbuffers(self) -> Dict[str, np.ndarray]:
        """``albedo`` (H, W, 3), ``normal`` (H, W, 3), ``depth`` (H, W), ``emitter``
        (H, W), and ``medium`` (H, W) in scenes with media; float32."""
        return self._native.gbuffers()

    def steady(self) -> np.ndarray:
        """The steady-state (time-integrated) mean image, float64 (H, W, C)."""
        return self._native.steady()

    def published_arrays(self) -> Dict[str, np.ndarray]:
        """The published pipeline's arrays of this bundle, as its denoiser takes them:
        ``noisy`` (the linear video), ``estimands`` and ``estimands_variance`` (theta and
        V in the bundle's transform; render with ``transform="yeo-johnson:0.5"`` for
        the published pipeline's), ``albedo`` and ``normals``; float32. ``tstat export
        --published DIR`` writes them as files."""
        theta, variance = self._native.estimates()
        g = self._native.gbuffers()
        return {
            "noisy": self._native.mean(),
            "estimands": theta,
            "estimands_variance": variance,
            "albedo": g["albedo"],
            "normals": g["normal"],
        }

    def save(self, path: PathLike, force: bool = False) -> "Bundle":
        """Copies the bundle to ``path`` (refused if it exists, unless ``force``) and
        returns the copy. The copy is written under a temporary name, then renamed."""
        target = os.path.abspath(os.fspath(path))
        if os.path.lexists(target) and not force:
            raise TstatError(f"{target} already exists; pass force=True to replace it")
        parent = os.path.dirname(target)
        staging = tempfile.mkdtemp(prefix=".tstat-save-", dir=parent)
        try:
            copy = os.path.join(staging, "bundle")
            shutil.copytree(self.path, copy)
            if os.path.lexists(target):
                old = os.path.join(staging, "old")
                os.rename(target, old)
            os.rename(copy, target)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
        return load(target)

    def __repr__(self) -> str:
        m = self.manifest
        return (
            f"<tstat.Bundle {self.path!r}: {m['width']}x{m['height']} px, "
            f"{m['bins']} bins, {m['spp']} spp>"
        )


def _progress(progress: Union[bool, ProgressCallback, None]) -> Optional[ProgressCallback]:
    if progress is None or progress is False:
        return None
    if callable(progress):
        return progress
    try:
        from tqdm.auto import tqdm  # type: ignore[import-not-found]
    except ImportError:
        return None
    bars: Dict[str, Any] = {}

    def show(stage: str, done: int, total: int, status: str) -> None:
        bar = bars.get(stage)
        if bar is None:
            bar = bars[stage] = tqdm(total=total, desc=stage, unit=" paths", unit_scale=True)
        bar.update(done - bar.n)
        if status:
            bar.set_postfix_str(status, refresh=False)
        if done >= total:
            bar.close()

    return show


def _path_of(bundle: Union[Bundle, PathLike]) -> str:
    return bundle.path if isinstance(bundle, Bundle) else os.fspath(bundle)


def run(*argv: str) -> None:
    """Runs a command in-process, as ``tstat ARGV...`` on the command line would
    (e.g. ``tstat.run("export", "b.tstats", "--out", "noisy.npy")``)."""
    _tstat.run([os.fspath(a) for a in argv])


def render(
    scene: PathLike,
    spp: int,
    params: Optional[Mapping[str, Any]] = None,
    seed: int = 0,
    out: Optional[PathLike] = None,
    *,
    progress: Union[bool, ProgressCallback, None] = True,
    verbose: bool = False,
    **render_options: Any,
) -> Bundle:
    """Renders ``scene`` (Mitsuba 3 XML) with ``spp`` samples per pixel (the mean with
    ``adaptive=True``) and returns its bundle: streamed to ``out`` if given (refused if
    it exists unless ``force=True``), else to a temporary folder removed with the
    returned object.

    ``params`` sets the scene's ``<default>`` values (``-D name=value``). ``seed`` is
    the job's seed (``--seed``): it replaces the scene's sampler seed, 0 included.
    ``render_options`` are ``tstat render``'s flags: ``width``, ``height``, ``bins``,
    ``start_opl``, ``bin_width_opl``, ``max_depth``, ``pixel_sampling``,
    ``replicates``, ``transform`` (``"yeo-johnson:0.5"``), ``adaptive``,
    ``target_error``, ``time_budget``, ``pilot_spp``, ``adaptive_measure``,
    ``threads``, ``max_memory``, ``shard``, ``time_origin``, ``mode`` (``"rgb"``,
    ``"spectral"``, docs/spectral.md; ``"mono"`` or ``"mono_polarized"``: one channel,
    or the four Stokes components S0..S3; ``"spectral_polarized"``: S0..S3 of each sRGB
    channel, twelve channels; docs/polarization.md), ``unit_m``, ``force``.

    ``progress``: True shows tqdm bars if tqdm is installed; a callable gets
    ``(stage, done, total, status)`` ten times a second; False shows nothing. Ctrl-C
    stops the render after the rows under way (nothing is written) and raises
    KeyboardInterrupt. ``verbose`` prints what ``tstat render`` prints to stderr.
    Same seed, same bits, on any number of threads.
    """
    spp = whole("spp", spp)
    seed = whole("seed", seed)
    owned = None
    if out is None:
        owned = tempfile.mkdtemp(prefix="tstat-")
        target = os.path.join(owned, "render.tstats")
    else:
        target = os.fspath(out)
    argv = ["render", os.fspath(scene), "--out", target, "--spp", str(spp), "--seed", str(seed)]
    argv += defines(params) + flags(render_options)
    try:
        notes = _tstat.render(argv, _progress(progress))
    except BaseException:
        if owned is not None:
            shutil.rmtree(owned, ignore_errors=True)
        raise
    if verbose:
        for line in notes:
            print(line, file=sys.stderr)
    return Bundle(_tstat.Bundle(target, owned))


def load(path: PathLike) -> Bundle:
    """Opens the bundle at ``path`` (checked as every reader of the command line
    checks it)."""
    return Bundle(_tstat.Bundle(os.fspath(path)))


def denoise(
    bundle: Union[Bundle, PathLike],
    method: str = "tstat",
    out: Optional[PathLike] = None,
    **options: Any,
) -> np.ndarray:
    """Denoises ``bundle`` and returns the volume, float32 (H, W, T, C): bit for bit the
    array ``tstat denoise --method METHOD`` writes (also written to ``out`` if given).
    ``options`` are ``tstat denoise``'s flags (``radius``, ``temporal_radius``,
    ``alpha``, ``threads``, ``max_memory``, ``force``, ...)."""
    with tempfile.TemporaryDirectory(prefix="tstat-") as scratch:
        target = os.fspath(out) if out is not None else os.path.join(scratch, "denoised.npy")
        run("denoise", _path_of(bundle), "--out", target, "--method", method, *flags(options))
        return np.load(target)


def denoise_arrays(
    noisy: Any,
    mean: Any,
    variance: Any,
    spp: int,
    albedo: Any,
    normal: Any,
    depth: Any = None,
    transform: str = "yeo-johnson",
    lam: float = 0.5,
    *,
    emitter: Any = None,
    pixel_spp: Any = None,
    bin_width_opl: Optional[float] = None,
    stratified: bool = False,
    method: str = "tstat",
    **options: Any,
) -> np.ndarray:
    """Denoises per-voxel estimates from another renderer: the published pipeline's
    arrays as its renderer returns them. ``noisy`` is the linear video (H, W, T, 3),
    ``mean`` the estimand theta (skewness-corrected mean of the transformed samples)
    and ``variance`` its variance V, both in ``transform`` with ``lam``
    (``"yeo-johnson"``, ``"box-cox"`` or ``"identity"``); ``albedo`` and ``normal``
    (H, W, 3); ``spp`` the samples per pixel behind them. f32 or f64, finite, V >= 0.

    Returns float32 (H, W, T, 3): bit for bit ``tstat denoise --from-arrays`` (and, on
    arrays exported from a tstat bundle with their ``depth``, ``emitter`` and
    ``bin_width_opl``, bit for bit ``tstat denoise`` of the bundle). Without ``emitter``
    and ``depth`` tstat's filter loses its emitter class and camera-depth alignment
    (docs/python.md measures the cost); ``method="published"`` uses neither.
    ``options`` are ``tstat denoise``'s filter flags (``radius``, ``alpha``, ...).
    """
    spp = whole("spp", spp)
    kind = "identity" if transform == "identity" else f"{transform}:{lam!r}"
    arrays = {
        "noisy.npy": noisy,
        "estimands.npy": mean,
        "estimands_variance.npy": variance,
        "albedo.npy": albedo,
        "normals.npy": normal,
        "depth.npy": depth,
        "emitter.npy": emitter,
        "pixel_spp.npy": pixel_spp,
    }
    with tempfile.TemporaryDirectory(prefix="tstat-") as scratch:
        folder = os.path.join(scratch, "arrays")
        os.mkdir(folder)
        for name, value in arrays.items():
            if value is not None:
                np.save(os.path.join(folder, name), np.ascontiguousarray(value), allow_pickle=False)
        meta = {"spp": spp, "transform": kind, "stratified": bool(stratified)}
        if bin_width_opl is not None:
            meta["bin_width_opl"] = float(bin_width_opl)
        with open(os.path.join(folder, "meta.json"), "w") as f:
            json.dump(meta, f)
        target = os.path.join(scratch, "denoised.npy")
        run("denoise", "--from-arrays", folder, "--spp", str(spp), "--transform", kind,
            "--out", target, "--method", method, *flags(options))
        return np.load(target)


def merge(
    bundles: Sequence[Union[Bundle, PathLike]],
    out: Optional[PathLike] = None,
    **options: Any,
) -> Bundle:
    """Merges bundles of the same scene and settings rendered with other seeds (or the
    shards of one job) into one, as ``tstat merge``; to ``out``, else to a temporary
    folder removed with the returned object. ``options``: ``partial``,
    ``max_memory``, ``force``."""
    if isinstance(bundles, (str, os.PathLike, Bundle)):
        raise TypeError("merge takes a list of bundles")
    paths = [_path_of(b) for b in bundles]
    owned = None
    if out is None:
        owned = tempfile.mkdtemp(prefix="tstat-")
        target = os.path.join(owned, "merged.tstats")
    else:
        target = os.fspath(out)
    try:
        run("merge", *paths, "--out", target, *flags(options))
    except BaseException:
        if owned is not None:
            shutil.rmtree(owned, ignore_errors=True)
        raise
    return Bundle(_tstat.Bundle(target, owned))


from . import nlos, report  # noqa: E402  (they use the names above)
