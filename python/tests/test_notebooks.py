"""The example notebooks (examples/*.ipynb) run from the first cell to the last
(nbclient), each in a scratch copy of the folder so their outputs stay out of the
repository. Their own asserts check what they show."""

import glob
import os
import shutil

import nbformat
import pytest
from nbclient import NotebookClient

from conftest import ROOT

NOTEBOOKS = sorted(glob.glob(os.path.join(ROOT, "examples", "*.ipynb")))


def test_there_are_notebooks():
    names = {os.path.basename(n) for n in NOTEBOOKS}
    assert names >= {"render_denoise.ipynb", "convergence.ipynb", "nlos.ipynb", "published_arrays.ipynb"}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=os.path.basename)
def test_notebook_runs(path, tmp_path):
    work = tmp_path / "examples"
    work.mkdir()
    os.symlink(os.path.join(ROOT, "scenes"), tmp_path / "scenes")
    shutil.copy(path, work)
    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(work)}}).execute()
    errors = [o for c in nb.cells for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors
