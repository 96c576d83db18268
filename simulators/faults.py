"""Seeded fault injection on a byte stream: bit errors, dropped and duplicated bytes, garbage bursts.

The injector reports which bytes of the original stream it touched, so a test can tell exactly
which frames went out intact and must be delivered.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class FaultLog:
    """Original-stream byte offsets that were hit; an insertion lies *before* its offset."""

    flipped: list[np.ndarray] = field(default_factory=list)
    dropped: list[np.ndarray] = field(default_factory=list)
    duplicated: list[np.ndarray] = field(default_factory=list)
    inserted_before: list[np.ndarray] = field(default_factory=list)

    def damaged_frames(self, frame_size: int) -> set[int]:
        """Indices of the frames (of a stream of back-to-back frames) that did not go out intact."""
        hit: set[int] = set()
        for arr in (*self.flipped, *self.dropped):
            hit.update((arr // frame_size).tolist())
        for arr in self.inserted_before:
            inside = arr[arr % frame_size != 0]
            hit.update((inside // frame_size).tolist())
        for arr in self.duplicated:
            # a repeated first or last byte leaves the frame itself intact
            inside = arr[(arr % frame_size != 0) & (arr % frame_size != frame_size - 1)]
            hit.update((inside // frame_size).tolist())
        return hit


@dataclass
class ByteFaults:
    """Per-byte fault rates; ``bit_error_rate`` is per bit. Same seed, same faults."""

    seed: int = 0
    bit_error_rate: float = 0.0
    drop_rate: float = 0.0
    duplicate_rate: float = 0.0
    garbage_rate: float = 0.0
    garbage_max_len: int = 32
    log: FaultLog | None = None

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._offset = 0  # original-stream offset of the next byte

    @property
    def active(self) -> bool:
        return any((self.bit_error_rate, self.drop_rate, self.duplicate_rate, self.garbage_rate))

    def apply(self, data: bytes) -> bytes:
        """The bytes as they arrive after the faults."""
        n = len(data)
        base = self._offset
        self._offset += n
        if not self.active or n == 0:
            return data
        rng = self._rng
        buf = np.frombuffer(data, dtype=np.uint8).copy()
        n_flips = rng.binomial(n * 8, self.bit_error_rate) if self.bit_error_rate else 0
        if n_flips:
            bits = rng.choice(n * 8, n_flips, replace=False)
            np.bitwise_xor.at(buf, bits // 8, (1 << (bits % 8)).astype(np.uint8))
            self._record("flipped", np.unique(bits // 8) + base)
        drop = rng.random(n) < self.drop_rate if self.drop_rate else np.zeros(n, bool)
        dup = rng.random(n) < self.duplicate_rate if self.duplicate_rate else np.zeros(n, bool)
        dup &= ~drop
        self._record("dropped", np.flatnonzero(drop) + base)
        self._record("duplicated", np.flatnonzero(dup) + base)
        counts = np.where(drop, 0, np.where(dup, 2, 1))
        pieces = np.repeat(buf, counts)
        if not self.garbage_rate:
            return pieces.tobytes()
        # garbage bursts go in front of original bytes chosen at the garbage rate
        starts = np.flatnonzero(rng.random(n) < self.garbage_rate)
        if len(starts) == 0:
            return pieces.tobytes()
        self._record("inserted_before", starts + base)
        position = np.concatenate(([0], np.cumsum(counts)))[starts]
        out, last = [], 0
        for pos in position:
            out.append(pieces[last:pos].tobytes())
            length = int(rng.integers(1, self.garbage_max_len + 1))
            out.append(rng.integers(0, 256, length, np.uint8).tobytes())
            last = pos
        out.append(pieces[last:].tobytes())
        return b"".join(out)

    def _record(self, kind: str, offsets: np.ndarray) -> None:
        if self.log is not None and len(offsets):
            getattr(self.log, kind).append(offsets)
