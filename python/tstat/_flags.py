"""Keywords to command-line flags: the package's options are the command line's, so
its checks and messages are too (``bin_width_opl=0.01`` is ``--bin-width-opl 0.01``)."""

from __future__ import annotations

import numbers
import os
from typing import Any, List, Mapping


def flag_value(value: Any) -> str:
    """A keyword's value as the command line spells it."""
    if isinstance(value, (list, tuple)):
        return ",".join(flag_value(v) for v in value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


def flags(options: Mapping[str, Any]) -> List[str]:
    """``{"bins": 64, "adaptive": True, "threads": None}`` -> ``["--bins", "64",
    "--adaptive"]``: True is the bare flag, False and None leave it out."""
    argv: List[str] = []
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            argv.append(flag)
        else:
            argv += [flag, flag_value(value)]
    return argv


def defines(params: Mapping[str, Any] | None) -> List[str]:
    """Scene ``<default>`` values: ``{"spp": 4}`` -> ``["-D", "spp=4"]``."""
    argv: List[str] = []
    for key, value in (params or {}).items():
        argv += ["-D", f"{key}={flag_value(value)}"]
    return argv


def whole(name: str, value: Any) -> int:
    """An integer argument (``True`` is not one)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an int, not {type(value).__name__}")
    return int(value)
