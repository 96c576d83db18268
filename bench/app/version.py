"""The software version recorded in every campaign file and printed by ``wfsbench --version``."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version


def software_version() -> str:
    try:
        return version("wfs-bench")
    except PackageNotFoundError:
        return "unknown"
