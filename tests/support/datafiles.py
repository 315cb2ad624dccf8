"""Where the tests find the real recordings: ``PFSLAM_DATA``, else ``../shared/data``
(next to the project folder). Importable from every test folder (``pythonpath = ["tests"]``
in pyproject.toml)."""

import os
from pathlib import Path

import pytest

DATA = Path(os.environ.get("PFSLAM_DATA") or Path(__file__).resolve().parents[3] / "shared" / "data")


def need(rel: str) -> Path:
    """The path of a recording, or skip the test (naming where it looked) if it is not there."""
    p = DATA / rel
    if not p.exists():
        pytest.skip(f"real recording {p} not found (set PFSLAM_DATA to the data folder)")
    return p
