"""A measurement's channel kept on disk while it is compensated: its float64 samples appended block
by block to an unlinked temporary file, then read back by slice.

A file of any size (an MDF4 file that can be read only front to back in fragments, a CSV file whose
length is known only at its end) is read once into spooled channels; everything that follows (the
checks, the statistics, the noise estimate's blocks spread over the record, the filters' windows)
reads only the slices it needs, so a process holds a few blocks, never the record. The file is
unlinked at once: nothing is left behind, whatever ends the process (``TMPDIR`` chooses its
folder: 8 bytes per sample and channel).
"""

from __future__ import annotations

import os
import tempfile
import weakref

import numpy as np

_ITEM_BYTES = np.dtype(np.float64).itemsize


class SpooledChannel:
    """One channel's samples on disk: :meth:`append` blocks in order, then slice it like a 1-D array
    (``channel[a:b]`` reads those samples into a new array; ``size``, ``shape``, ``len``;
    ``numpy.asarray(channel)`` reads it whole)."""

    def __init__(self) -> None:
        fd, name = tempfile.mkstemp(prefix="wfsbench-spool-")
        os.unlink(name)
        self._fd = fd
        self._finalizer = weakref.finalize(self, os.close, fd)
        self.size = 0

    def append(self, values: np.ndarray) -> None:
        data = np.ascontiguousarray(values, dtype=np.float64).tobytes()
        written = os.pwrite(self._fd, data, self.size * _ITEM_BYTES)
        if written != len(data):
            raise OSError(f"the spool's temporary file took {written} of {len(data)} bytes (disk full?)")
        self.size += len(data) // _ITEM_BYTES

    @property
    def shape(self) -> tuple[int]:
        return (self.size,)

    @property
    def ndim(self) -> int:
        return 1

    def __len__(self) -> int:
        return self.size

    def __getitem__(self, index: slice) -> np.ndarray:
        if not isinstance(index, slice):
            raise TypeError("a spooled channel is read by slice (channel[a:b])")
        start, stop, step = index.indices(self.size)
        if step != 1:
            raise TypeError("a spooled channel is read by contiguous slice")
        if stop <= start:
            return np.empty(0)
        data = os.pread(self._fd, (stop - start) * _ITEM_BYTES, start * _ITEM_BYTES)
        return np.frombuffer(data, dtype=np.float64).copy()

    def __array__(self, dtype: np.dtype | None = None, copy: bool | None = None) -> np.ndarray:
        """The whole channel read into memory (``numpy.asarray``): for a record known to be short."""
        whole = self[:]
        return whole if dtype is None else whole.astype(dtype)

    def close(self) -> None:
        """Free the temporary file now (else when the channel is collected)."""
        self._finalizer()
