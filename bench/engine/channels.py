"""From WFS frames to the named, calibrated channels a run records.

Every frame is kept as it came (sequence counter, sample clock, status bits, the six raw loads in
the sensor's rotating frame, wheel angle and speed) and, beside it, the loads calibrated, tared and
rotated to the non-rotating wheel frame, and the aux inputs as the bench configuration wires them
(:class:`~sequences.channels.AuxInput`: by default the bench displacement ``z_base_m``, the plate
force ``f_plate_n`` and the hub acceleration ``a_hub_m_s2``, each with its role). Channel names
carry their unit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from drivers.wfs_frame import AUX_FIELDS, FORCE_FIELDS
from drivers.wfs_transform import LoadProcessor, loads_of
from sequences.channels import DEFAULT_AUX_INPUTS, STANDARD_CHANNELS, AuxInput, Channel, ChannelSet, Role

_LOAD_UNITS = ("N", "N", "N", "N m", "N m", "N m")
_LOAD_SUFFIX = ("n", "n", "n", "nm", "nm", "nm")
WHEEL_LOADS = tuple(f"{name}_wfs_{suffix}" for name, suffix in zip(FORCE_FIELDS, _LOAD_SUFFIX, strict=True))
RAW_LOADS = tuple(f"{name}_raw_{suffix}" for name, suffix in zip(FORCE_FIELDS, _LOAD_SUFFIX, strict=True))


def _wheel_load(name: str, unit: str, field: str) -> Channel:
    """A calibrated load in the wheel frame; Fz is the WFS's vertical force the analysis uses."""
    fz = STANDARD_CHANNELS[Role.WFS_FZ]
    if name == fz.name:
        return fz
    return Channel(name, unit, f"{field} in the non-rotating wheel frame, calibrated and tared")


class FrameChannels:
    """Turns blocks of frames into the recorded columns; owns the calibration and the host tare."""

    def __init__(
        self, aux: Sequence[AuxInput] = DEFAULT_AUX_INPUTS, loads: LoadProcessor | None = None
    ) -> None:
        if len(aux) != len(AUX_FIELDS):
            raise ValueError(f"{len(AUX_FIELDS)} aux inputs must be described, got {len(aux)}")
        self.aux = tuple(aux)
        self.loads = loads or LoadProcessor()
        self.recorded = ChannelSet(
            (
                Channel("seq", "", "frame sequence counter (link accounting)", "u4"),
                Channel("sample", "", "acquisition sample index since the stream started", "u4"),
                Channel("status", "", "frame status bits (overloads, ADC fault, tare, sync inputs)", "u2"),
                *(
                    Channel(name, unit, f"{field} in the sensor's rotating frame, as received")
                    for name, unit, field in zip(RAW_LOADS, _LOAD_UNITS, FORCE_FIELDS, strict=True)
                ),
                Channel("angle_rad", "rad", "wheel angle about the wheel axis"),
                Channel("speed_rad_s", "rad/s", "wheel speed"),
                *(
                    _wheel_load(name, unit, field)
                    for name, unit, field in zip(WHEEL_LOADS, _LOAD_UNITS, FORCE_FIELDS, strict=True)
                ),
                *(a.channel for a in self.aux),
            )
        )

    @property
    def displacement(self) -> str:
        """The bench displacement's channel: amplitudes and spans are measured on it."""
        return self.recorded.name_of(Role.BENCH_DISPLACEMENT)

    def specs(self) -> tuple[Channel, ...]:
        """The recorded channels, in recording order."""
        return self.recorded.channels

    def columns(self, frames: np.ndarray) -> Mapping[str, np.ndarray]:
        """The recorded columns of a block of frames (``FRAME_DTYPE``)."""
        out: dict[str, np.ndarray] = {
            "seq": frames["seq"].astype(np.uint32),
            "sample": frames["sample"].astype(np.uint32),
            "status": frames["status"].astype(np.uint16),
        }
        raw = loads_of(frames)
        for i, name in enumerate(RAW_LOADS):
            out[name] = raw[:, i].astype(np.float32)
        out["angle_rad"] = frames["angle_rad"].astype(np.float32)
        out["speed_rad_s"] = frames["speed_rad_s"].astype(np.float32)
        wheel = self.loads.wheel_loads(frames)
        for i, name in enumerate(WHEEL_LOADS):
            out[name] = wheel[:, i].astype(np.float32)
        for field, aux in zip(AUX_FIELDS, self.aux, strict=True):
            out[aux.channel.name] = (frames[field].astype(np.float64) * aux.scale).astype(np.float32)
        return out
