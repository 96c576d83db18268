"""Response limits with graded actions, declared once: the bench configuration sets them, the engine
checks every block of frames against them, and the drive of grids and sweeps is lowered (notched)
where a response would pass them.

A limit is a profile against frequency on the channel playing one role (WFS Fz, plate force, hub
acceleration): an *alarm* level below an *abort* level, each with its action. The levels bound the
channel's absolute value (its unit), read at the excitation's frequency by linear interpolation
between the profile's points and held beyond its ends. Every interlock of the bench has an action
too (:data:`GRADED_INTERLOCKS` may be given another one than ``interlock``).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from sequences.channels import Role


class LimitAction(enum.StrEnum):
    """What a limit does when a response passes it, from the mildest."""

    INDICATE = "indicate"  # an event only: the run goes on
    HOLD = "hold"  # pause the sequence: the point under way tapered out, repeated on resume
    STOP = "stop"  # taper out and end the sequence (aborted)
    INTERLOCK = "interlock"  # taper out and end the sequence interlocked: a reset is needed

    @property
    def severity(self) -> int:
        return tuple(LimitAction).index(self)


#: The roles a response limit may watch.
LIMITED_ROLES = (Role.WFS_FZ, Role.PLATE_FORCE, Role.HUB_ACCELERATION)
#: The bench's own interlocks whose action a configuration may choose (the link losses and the
#: controller's own interlock always interlock: nothing the bench does can be trusted after them).
GRADED_INTERLOCKS = ("displacement_limit", "force_limit", "wfs_overload")
#: A notch lowers the drive until the predicted response is this fraction of the alarm level: the
#: margin covers the model's error and the noise, so that a notched point does not raise the alarm.
NOTCH_FRACTION = 0.9


@dataclass(frozen=True, slots=True)
class LimitProfile:
    """Levels against frequency: ``levels[i]`` at ``freqs_hz[i]`` (ascending), linear between, held
    beyond the ends."""

    freqs_hz: tuple[float, ...]
    levels: tuple[float, ...]

    def at(self, freq_hz: float | np.ndarray) -> np.ndarray:
        return np.interp(freq_hz, self.freqs_hz, self.levels)


@dataclass(frozen=True, slots=True)
class ResponseLimit:
    """A response limit named ``name`` on the channel of ``role``: ``alarm`` below ``abort`` at every
    frequency, each with its action; ``notch``: grids and sweeps are lowered where the predicted
    response would pass :data:`NOTCH_FRACTION` of the alarm level."""

    name: str
    role: Role
    alarm: LimitProfile
    abort: LimitProfile
    alarm_action: LimitAction = LimitAction.INDICATE
    abort_action: LimitAction = LimitAction.INTERLOCK
    notch: bool = True

    def notch_level(self, freq_hz: float | np.ndarray) -> np.ndarray:
        """The response a notch lowers the drive to at ``freq_hz``."""
        return NOTCH_FRACTION * self.alarm.at(freq_hz)
