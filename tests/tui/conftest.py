"""The UI's fixtures: the app on the simulated bench, fast or paced in real time."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.tui.app import WfsBenchApp

FILES = Path(__file__).parent / "files"


@pytest.fixture
def app(tmp_path: Path) -> WfsBenchApp:
    """The UI on the default simulated bench (as fast as the engine drains it), its controller's
    watchdog set for a starved machine (files/fast.toml)."""
    return WfsBenchApp(FILES / "fast.toml", tmp_path / "campaign.h5")


@pytest.fixture
def paced_app(tmp_path: Path) -> WfsBenchApp:
    """The UI on the simulated bench paced in real time: a 60 s dwell lasts 60 s."""
    return WfsBenchApp(FILES / "paced.toml", tmp_path / "campaign.h5")
