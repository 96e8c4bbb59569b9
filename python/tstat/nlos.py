"""NLOS captures (confocal or exhaustive wall scans rendered by tstat, or y-tal HDF5
captures) reconstructed into a volume of the hidden scene, as ``tstat nlos
reconstruct``."""

from __future__ import annotations

import os
import tempfile
from typing import Any, Sequence, Union

import numpy as np

from . import Bundle, PathLike, _path_of, run
from ._flags import flag_value, flags

__all__ = ["reconstruct"]


def reconstruct(
    capture: Union[Bundle, PathLike],
    method: str,
    volume: Union[str, Sequence[float]],
    voxels: Union[str, Sequence[int]],
    out: Any = None,
    **options: Any,
) -> np.ndarray:
    """Reconstructs ``capture`` (a tstat capture bundle or a y-tal ``.hdf5``) with
    ``method`` (``bp``, ``fbp``, ``pf``, ``fk``, ``lct``, ...) on the voxel grid whose
    first and last centres are ``volume`` = (x0, x1, y0, y1, z0, z1) with ``voxels`` =
    (NX, NY, NZ), and returns it, float32 (NX, NY, NZ): bit for bit what ``tstat nlos
    reconstruct`` writes (also to ``out`` if given). ``options``: ``wl_mean``,
    ``wl_sigma``, ``snr``, ``denoised``, ``denoise_with``, ``max_memory``, ``force``."""
    with tempfile.TemporaryDirectory(prefix="tstat-") as scratch:
        target = os.fspath(out) if out is not None else os.path.join(scratch, "volume.npy")
        run(
            "nlos", "reconstruct", _path_of(capture),
            "--method", method,
            "--volume", flag_value(volume),
            "--voxels", flag_value(voxels),
            "--out", target,
            *flags(options),
        )
        return np.load(target)
