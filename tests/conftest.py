"""Shared fixtures: the real measured data in ../shared/data (read-only)."""
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data():
    """Path of ../shared/data; skips the test with a clear message when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is absent (it ships beside the repo in CI)")
    return SHARED_DATA


@pytest.fixture(scope="session")
def shared_data_optional():
    """Path of ../shared/data, or None when it is absent (the test decides what to skip)."""
    return SHARED_DATA if SHARED_DATA.is_dir() else None
