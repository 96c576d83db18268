"""From raw sensor channels to wheel loads: calibration matrix, tare, rotating to non-rotating.

The measuring rim turns with the wheel, so its x and z axes rotate about the wheel axis y with
the wheel angle. Loads in the non-rotating wheel frame follow by a rotation about y (the paper,
section 2.2): with the angle ``theta`` a right-hand rotation about +y,

    Fx =  cos(theta) Fx' + sin(theta) Fz'        Mx =  cos(theta) Mx' + sin(theta) Mz'
    Fz = -sin(theta) Fx' + cos(theta) Fz'        Mz = -sin(theta) Mx' + cos(theta) Mz'

while Fy and My, along the axis, are unchanged. The order of processing is: calibration/crosstalk
matrix on the raw channels, tare (an offset of the sensor, so taken in the rotating frame), then
the rotation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.wfs_frame import FORCE_FIELDS


def loads_of(frames: np.ndarray) -> np.ndarray:
    """The six load channels of a block of frames as an ``(n, 6)`` float64 array (Fx Fy Fz Mx My Mz)."""
    return np.column_stack([frames[name].astype(np.float64) for name in FORCE_FIELDS]).reshape(-1, 6)


def rotate_to_wheel_frame(loads_rot: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Rotate ``(n, 6)`` loads from the sensor's rotating frame to the non-rotating wheel frame."""
    loads_rot = np.asarray(loads_rot, dtype=float)
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    out = loads_rot.copy()
    for x, z in ((0, 2), (3, 5)):
        out[:, x] = c * loads_rot[:, x] + s * loads_rot[:, z]
        out[:, z] = -s * loads_rot[:, x] + c * loads_rot[:, z]
    return out


@dataclass
class LoadProcessor:
    """Calibration (6x6 matrix, crosstalk included), tare and rotation of the six load channels.

    ``matrix`` maps raw channels to calibrated loads: ``calibrated = raw @ matrix.T``.
    """

    matrix: np.ndarray = field(default_factory=lambda: np.eye(6))
    offset: np.ndarray = field(default_factory=lambda: np.zeros(6))

    def __post_init__(self) -> None:
        self.matrix = np.asarray(self.matrix, dtype=float)
        self.offset = np.asarray(self.offset, dtype=float)
        if self.matrix.shape != (6, 6) or not np.all(np.isfinite(self.matrix)):
            raise ValueError(f"calibration matrix must be a finite 6x6 array, got shape {self.matrix.shape}")
        if np.linalg.cond(self.matrix) > 1e6:
            raise ValueError("calibration matrix is (nearly) singular")
        if self.offset.shape != (6,):
            raise ValueError(f"tare offset must have 6 entries, got shape {self.offset.shape}")

    def calibrate(self, raw: np.ndarray) -> np.ndarray:
        """Calibrated loads in the rotating frame, tare removed."""
        return np.asarray(raw, dtype=float) @ self.matrix.T - self.offset

    def tare(self, raw: np.ndarray) -> None:
        """Take the mean calibrated load of ``raw`` (n, 6) as the new zero."""
        raw = np.asarray(raw, dtype=float)
        if raw.ndim != 2 or raw.shape[1] != 6 or len(raw) == 0:
            raise ValueError(f"tare needs an (n, 6) block with n > 0, got shape {raw.shape}")
        self.offset = np.mean(raw @ self.matrix.T, axis=0)

    def wheel_loads(self, frames: np.ndarray) -> np.ndarray:
        """Calibrated, tared loads in the non-rotating wheel frame for a block of frames, ``(n, 6)``."""
        return rotate_to_wheel_frame(self.calibrate(loads_of(frames)), frames["angle_rad"].astype(float))
