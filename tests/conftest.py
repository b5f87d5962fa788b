"""Shared fixtures: built-in rigs are cached by the registry, so loading is cheap."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"


@pytest.fixture(scope="session")
def quadruped():
    from rigmap.rigs import load

    return load("quadruped")


@pytest.fixture(scope="session")
def biped():
    from rigmap.rigs import load

    return load("biped")
