"""Files made once per test run and read by every test worker: a campaign that several test
modules read costs its recording or simulation once, not once per worker that runs one of them."""

from __future__ import annotations

import fcntl
from collections.abc import Callable
from pathlib import Path


def made_once(folder: Path, name: str, make: Callable[[Path], None]) -> Path:
    """``folder/made-once/name``, made by ``make`` (given a path to write) by the first worker to
    ask while the others wait on its lock; every later call returns it as made. A ``make`` that
    fails leaves nothing behind, so the next caller makes it again (and fails the same way). Read
    the file, never change it: other tests read it at the same time."""
    path = folder / "made-once" / name
    path.parent.mkdir(exist_ok=True)
    with open(path.with_name(f"{name}.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            making = path.with_name(f"making-{name}")
            making.unlink(missing_ok=True)
            make(making)
            making.rename(path)
    return path
