"""Fixtures: the repository's scenes and the command-line binary the API is checked
against (``target/release/tstat``, built by ``cargo test --release``; or $TSTAT_BIN)."""

import os
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="session")
def cli():
    path = os.environ.get("TSTAT_BIN", os.path.join(ROOT, "target", "release", "tstat"))
    if not os.path.exists(path):
        pytest.fail(f"{path} is missing: build it with `cargo build --release` (or set TSTAT_BIN)")

    def call(*args):
        r = subprocess.run([path, *map(str, args)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return r

    call.path = path
    return call


@pytest.fixture(scope="session")
def scene():
    return lambda name: os.path.join(ROOT, "scenes", name)
