"""Outputs written whole or not at all: each is written into a hidden temporary beside it, named
``.<name>.<pid>.partial[<suffix>]``, and moved into place once complete.

A process killed while writing (``kill -9``, a power cut) cannot remove its temporary; the next
command that writes into the same folder removes every temporary whose process is gone, so that
none is left for good and none of a command still running is touched.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

#: The name of a temporary: the output's name, the writing process's id, the marker, a suffix.
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.partial(?P<suffix>.*)$")


def temporary_beside(out: Path, suffix: str = "") -> Path:
    """The temporary of this process for ``out`` (not created); the folder's temporaries of
    processes that are gone are removed first."""
    remove_stale_temporaries(out.parent)
    return out.with_name(f".{out.name}.{os.getpid()}.partial{suffix}")


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: running
        return True
    return True


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Remove the temporaries in ``folder`` whose writing process is gone; return them."""
    removed = []
    try:
        entries = list(folder.iterdir())
    except OSError:  # a folder that cannot be listed: the write that follows says why
        return removed
    for path in entries:
        match = _TEMPORARY.match(path.name)
        if match is None or _running(int(match["pid"])):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed
