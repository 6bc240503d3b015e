"""Shared fixtures: the repository root, the `zeroset` binary the same checkout built, scenes."""

import os
import pathlib
import shutil

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def zeroset_binary() -> str:
    """The CLI built from this checkout (`cargo test`/`cargo build` put it under target/)."""
    explicit = os.environ.get("ZEROSET_BIN")
    if explicit:
        return explicit
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for profile in ("debug", "release"):
        candidate = target / profile / "zeroset"
        if candidate.exists():
            return str(candidate)
    found = shutil.which("zeroset")
    if found:
        return found
    raise RuntimeError("no zeroset binary: run `cargo build` first or set ZEROSET_BIN")


@pytest.fixture(scope="session")
def cli() -> str:
    return zeroset_binary()


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    return REPO
