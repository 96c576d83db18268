"""The simulated controller's drive memory: a drive file uploaded over the register map, block by
block, checked as it comes and played once complete (docs/protocols.md, *Drive files*).

An upload begins with its sample rate and length (``drive_rate_hz``, ``drive_length``); then each
request carries ``drive_offset`` and a ``drive_block`` of samples (mm), which must go on from the
samples received so far. What was received is reported back (``drive_loaded``, ``drive_crc32``)
so that the host can check the upload before it plays it.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping, Sequence

import numpy as np

from drivers.register_map import BLOCKS, ErrorCode
from sequences.limits import DRIVE_MAX_SAMPLES, DRIVE_RATE_RANGE_HZ
from simulators.plant.excitation import SampledDrive

#: The holding registers of an upload.
DRIVE_REGISTERS = frozenset({"drive_rate_hz", "drive_length", "drive_offset", "drive_block"})
BLOCK_SAMPLES = BLOCKS["drive_block"]


class DriveBuffer:
    """The drive being uploaded, or uploaded: its rate, length and the samples received so far."""

    def __init__(self, stroke_mm: float) -> None:
        self.stroke_mm = stroke_mm
        self.rate_hz = 1000.0
        self.length = 0
        self.loaded = 0
        self.crc32 = 0
        self.offset = 0  # the last block's offset (what the register reads)
        self.block: tuple[float, ...] = (0.0,) * BLOCK_SAMPLES
        self._samples = np.zeros(0, dtype="<f4")

    @property
    def complete(self) -> bool:
        return self.length >= 2 and self.loaded == self.length

    @property
    def peak_mm(self) -> float:
        return float(np.max(np.abs(self._samples[: self.loaded]))) if self.loaded else 0.0

    def registers(self) -> dict[str, object]:
        """What the holding registers read: the upload's rate and length, the last block written."""
        return {
            "drive_rate_hz": self.rate_hz,
            "drive_length": self.length,
            "drive_offset": self.offset,
            "drive_block": self.block,
        }

    def refusal(self, values: Mapping[str, object]) -> ErrorCode | None:
        """Why a write of the drive registers in ``values`` would be refused (INVALID_SETPOINT):
        a rate or length out of range, a block without its offset or at another offset than the
        samples received, a sample that is not finite or lies beyond the stroke."""
        rate = values.get("drive_rate_hz", self.rate_hz)
        lo, hi = DRIVE_RATE_RANGE_HZ
        if not (isinstance(rate, int | float) and math.isfinite(rate) and lo <= rate <= hi):
            return ErrorCode.INVALID_SETPOINT
        if "drive_length" in values and not 2 <= int(values["drive_length"]) <= DRIVE_MAX_SAMPLES:
            return ErrorCode.INVALID_SETPOINT
        if "drive_rate_hz" in values and "drive_length" not in values:
            return ErrorCode.INVALID_SETPOINT  # a rate belongs to the upload it begins
        if ("drive_block" in values) != ("drive_offset" in values):
            return ErrorCode.INVALID_SETPOINT
        if "drive_block" in values:
            loaded = 0 if "drive_length" in values else self.loaded
            block = np.asarray(values["drive_block"], dtype=float)
            if int(values["drive_offset"]) != loaded or not np.all(np.abs(block) <= self.stroke_mm):
                return ErrorCode.INVALID_SETPOINT  # NaN fails the comparison too
        return None

    def write(self, values: Mapping[str, object]) -> None:
        """Apply a write :meth:`refusal` accepted."""
        if "drive_length" in values:
            self.rate_hz = float(values.get("drive_rate_hz", self.rate_hz))
            self.length = int(values["drive_length"])
            self.loaded, self.crc32 = 0, 0
            self._samples = np.zeros(self.length, dtype="<f4")
        if "drive_block" in values:
            block: Sequence[float] = values["drive_block"]  # type: ignore[assignment]
            self.offset, self.block = int(values["drive_offset"]), tuple(block)
            taken = np.asarray(block[: max(self.length - self.loaded, 0)], dtype="<f4")
            self._samples[self.loaded : self.loaded + taken.size] = taken
            self.crc32 = zlib.crc32(taken.tobytes(), self.crc32)
            self.loaded += taken.size

    def waveform(self, taper_in_s: float, taper_out_s: float) -> SampledDrive:
        """The complete drive (m) as the generator plays it; ValueError when the upload is not
        complete or the tapers do not fit."""
        if not self.complete:
            raise ValueError(f"drive upload incomplete: {self.loaded} of {self.length} samples")
        return SampledDrive(self._samples.astype(float) / 1000, self.rate_hz, taper_in_s, taper_out_s)
