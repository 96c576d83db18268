"""Which files an index looks at, and what it knows of one before reading it.

Under each directory given, every file whose name ends in one of :data:`CAMPAIGN_SUFFIXES`
(any case) is a candidate, found lazily in a sorted walk (symbolic links to directories are not
followed: no loops); a file given by name is a candidate whatever its name. A candidate is known
by its absolute path, its size and modification time (:class:`FileStat`, one ``stat``) and, once
read, the SHA-256 of its bytes.
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from bench import locks
from bench.store.schema import campaign_key

CAMPAIGN_SUFFIXES = (".h5", ".hdf5")
_HASH_BLOCK_BYTES = 1 << 20


@dataclass(frozen=True)
class FileStat:
    """A file's size and modification time: equal stats are taken as equal contents (unless the
    index is asked to verify every hash)."""

    size_bytes: int
    mtime_ns: int

    @classmethod
    def of(cls, path: str | Path) -> FileStat:
        st = os.stat(path)
        return cls(st.st_size, st.st_mtime_ns)


def find_files(roots: Iterable[Path], suffixes: tuple[str, ...] = CAMPAIGN_SUFFIXES) -> Iterator[str]:
    """The absolute paths of the candidates under ``roots`` (directories or files), each once, in
    the order of a sorted walk of each root in turn: under a directory the files named with one of
    ``suffixes`` (any case), a file given by name whatever its name."""
    seen: set[str] = set()
    for root in roots:
        for path in _walk(root, suffixes):
            if path not in seen:
                seen.add(path)
                yield path


def _walk(root: Path, suffixes: tuple[str, ...]) -> Iterator[str]:
    top = os.path.abspath(root)
    if not os.path.isdir(top):
        yield top
        return
    for directory, subdirs, names in os.walk(top):
        subdirs.sort()
        for name in sorted(names):
            if name.lower().endswith(suffixes):
                yield os.path.join(directory, name)


def within(path: str, roots: Iterable[Path]) -> bool:
    """Whether the absolute ``path`` is one of ``roots`` or lies under one."""
    for root in roots:
        top = os.path.abspath(root)
        if path == top or path.startswith(top.rstrip(os.sep) + os.sep):
            return True
    return False


def sha256_of(path: str | Path) -> str:
    """The SHA-256 of the file's bytes, hex. OSError for anything but a regular file (a FIFO or a
    link to ``/dev/zero`` named ``*.h5`` would be read forever)."""
    if not stat.S_ISREG(os.stat(path).st_mode):
        raise OSError(errno.EINVAL, "not a regular file: a FIFO, a device or a socket")
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        while block := file.read(_HASH_BLOCK_BYTES):
            digest.update(block)
    return digest.hexdigest()


def writer_of(path: str | Path) -> locks.Holder | None:
    """The process that holds the campaign file's writer lock (a bench recording into it, on this
    machine), or None; only looks, never waits (:mod:`bench.locks`)."""
    return locks.holder_of(campaign_key(path))
