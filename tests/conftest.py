"""Shared fixtures and helpers for the cfdesign tests."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture
def shared_dir():
    """The project's shared/ folder (beside the checkout in CI); skip when absent."""
    if not SHARED.is_dir():
        pytest.skip(f"shared data folder not found at {SHARED} (it sits beside the checkout in CI)")
    return SHARED
