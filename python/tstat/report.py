"""Error against a reference versus time, as ``tstat report``."""

from __future__ import annotations

import csv
import os
import tempfile
from typing import Any, Dict, List, Optional, Sequence, Union

from . import PathLike, run
from ._flags import defines, flag_value, flags

__all__ = ["convergence"]


def _number(text: str) -> Union[int, float, str]:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def convergence(
    scene: PathLike,
    spp: Union[int, Sequence[int]],
    out: Optional[PathLike] = None,
    params: Optional[dict] = None,
    **options: Any,
) -> List[Dict[str, Union[int, float, str]]]:
    """Renders ``scene`` at each spp, denoises each, measures error against a reference
    and returns the table ``tstat report convergence`` writes (``results.csv``), one
    dict per row with numbers as numbers. The report's files (tables, plots, the cached
    reference) go to ``out`` if given, else to a temporary folder. ``options`` are the
    command's flags: ``reference``, ``reference_spp``, ``seed``, ``width``, ``bins``,
    ``no_adaptive``, ``reconstruct``, ...; ``params`` sets scene ``<default>``s."""
    spp_list = [spp] if isinstance(spp, int) else list(spp)
    with tempfile.TemporaryDirectory(prefix="tstat-") as scratch:
        target = os.fspath(out) if out is not None else os.path.join(scratch, "report")
        run(
            "report", "convergence", os.fspath(scene),
            "--spp", flag_value(spp_list),
            "--out", target,
            *defines(params), *flags(options),
        )
        with open(os.path.join(target, "results.csv"), newline="") as f:
            return [{k: _number(v) for k, v in row.items()} for row in csv.DictReader(f)]
