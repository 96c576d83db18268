"""Statistics of a record read block by block: a record on disk (:mod:`bench.store.spool`) or in
memory is visited in slices of :data:`BLOCK_SAMPLES`, so memory holds one block whatever the
record's length.

A record is anything sliced like a 1-D array with a ``size``: a numpy array, an h5py dataset, a
spooled channel.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np

#: Samples per block: 2 MB of float64, large enough that numpy's per-call cost vanishes.
BLOCK_SAMPLES = 1 << 18


class Record(Protocol):
    """A 1-D sequence of samples read by slice."""

    @property
    def size(self) -> int: ...

    def __getitem__(self, index: slice) -> np.ndarray: ...


def blocks(x: Record, size: int = BLOCK_SAMPLES) -> Iterator[tuple[int, np.ndarray]]:
    """``(start, samples)`` of ``x`` in order, ``size`` samples at a time (float64)."""
    for start in range(0, x.size, size):
        yield start, np.asarray(x[start : start + size], dtype=float)


@dataclass
class Moments:
    """Count, mean, spread, smallest and largest of the samples added so far (blocks merged with
    Chan's formula: as exact as one pass over the whole record)."""

    count: int = 0
    mean: float = 0.0
    m2: float = 0.0
    minimum: float = math.inf
    maximum: float = -math.inf

    def add(self, values: np.ndarray) -> None:
        values = values[np.isfinite(values)]
        n = values.size
        if not n:
            return
        mean = float(np.mean(values))
        m2 = float(np.sum((values - mean) ** 2))
        total = self.count + n
        delta = mean - self.mean
        self.m2 += m2 + delta**2 * self.count * n / total
        self.mean += delta * n / total
        self.count = total
        self.minimum = min(self.minimum, float(np.min(values)))
        self.maximum = max(self.maximum, float(np.max(values)))

    @property
    def std(self) -> float:
        """The standard deviation (population: ``numpy.std``'s); NaN without samples."""
        return math.sqrt(self.m2 / self.count) if self.count else math.nan

    @property
    def rms(self) -> float:
        """The root mean square; NaN without samples."""
        return math.sqrt(self.m2 / self.count + self.mean**2) if self.count else math.nan


def moments(x: Record) -> Moments:
    """The :class:`Moments` of the finite samples of ``x``, read block by block."""
    result = Moments()
    for _, block in blocks(x):
        result.add(block)
    return result
