"""Interlocks: small checks that stop the actuator when the bench leaves its safe envelope.

Each interlock looks at one :class:`Observation` (the newest samples, the controller's readback,
the links' health) and returns the reason to stop, or None. The engine checks every interlock after
every block of samples and while it waits for samples; the first reason stops the actuator with a
taper, marks the run with the interlock's name and reason, and keeps the data.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bench.engine.contracts import ControllerStatus
from drivers.wfs_frame import Status
from sequences.channels import ChannelSet, Role
from sequences.limits import BenchLimits

_OVERLOAD_BITS = {
    Status.OVERLOAD_FX: "Fx",
    Status.OVERLOAD_FY: "Fy",
    Status.OVERLOAD_FZ: "Fz",
    Status.OVERLOAD_MX: "Mx",
    Status.OVERLOAD_MY: "My",
    Status.OVERLOAD_MZ: "Mz",
    Status.OVERLOAD_AUX: "an aux input",
}


@dataclass(frozen=True)
class Observation:
    """What the interlocks see at one moment.

    ``columns``: the newest samples by channel name (``status`` among them, the frames' status bits),
    empty when none arrived; ``controller``: the last readback, if one was taken;
    ``actuator_link_fault``: the Modbus link's fault, if any; ``seconds_without_samples``: how long no
    byte has arrived at the WFS port while the acquisition should be streaming (0 otherwise, and 0
    while bytes wait at the port unread: a busy host is not a silent link).
    """

    columns: Mapping[str, np.ndarray]
    controller: ControllerStatus | None = None
    actuator_link_fault: str | None = None
    seconds_without_samples: float = 0.0


class Interlock(Protocol):
    name: str

    def check(self, seen: Observation) -> str | None:
        """The reason to stop now, or None."""
        ...


@dataclass(frozen=True)
class WfsOverload:
    """A load channel of the WFS (or one of its aux inputs) reports overload."""

    name: str = "WFS overload"

    def check(self, seen: Observation) -> str | None:
        status = seen.columns.get("status")
        if status is None or len(status) == 0:
            return None
        for bit, channel in _OVERLOAD_BITS.items():
            hits = np.flatnonzero(status & int(bit))
            if hits.size:
                return f"the WFS reports {channel} beyond its range"
        return None


@dataclass(frozen=True)
class ChannelLimit:
    """|channel| beyond ``limit`` (in the channel's unit) on any sample."""

    name: str
    channel: str
    limit: float
    unit: str

    def check(self, seen: Observation) -> str | None:
        values = seen.columns.get(self.channel)
        if values is None or len(values) == 0:
            return None
        peak = float(np.max(np.abs(values)))
        if peak > self.limit:
            return (
                f"{self.channel} reached {peak:.4g} {self.unit}, beyond the {self.limit:g} {self.unit} limit"
            )
        return None


def displacement_limit(limit_mm: float, channel: str) -> ChannelLimit:
    """|bench displacement| (``channel``, m) beyond ``limit_mm``."""
    return ChannelLimit("displacement limit", channel, limit_mm / 1e3, "m")


def force_limit(limit_n: float, channel: str) -> ChannelLimit:
    """|plate force| (``channel``, N) beyond ``limit_n``."""
    return ChannelLimit("force limit", channel, limit_n, "N")


@dataclass(frozen=True)
class ControllerInterlock:
    """The controller itself tripped (its limits, its watchdog) or was e-stopped."""

    name: str = "controller interlock"

    def check(self, seen: Observation) -> str | None:
        if seen.controller is None:
            return None
        return seen.controller.interlock_reason


@dataclass(frozen=True)
class ActuatorLinkLost:
    """The Modbus link failed: the heartbeat cannot be trusted to reach the controller."""

    name: str = "actuator link lost"

    def check(self, seen: Observation) -> str | None:
        return seen.actuator_link_fault


@dataclass(frozen=True)
class SerialLinkLost:
    """No WFS frame for ``timeout_s`` while the acquisition should stream."""

    timeout_s: float = 0.5
    name: str = "WFS link lost"

    def check(self, seen: Observation) -> str | None:
        if seen.seconds_without_samples > self.timeout_s:
            return f"no WFS frame for {seen.seconds_without_samples:.2f} s (limit {self.timeout_s:g} s)"
        return None


def standard_interlocks(
    channels: ChannelSet, limits: BenchLimits, *, serial_timeout_s: float = 0.5
) -> tuple[Interlock, ...]:
    """The interlocks every run is guarded by: the channel limits trip at the bench's stroke and
    plate force (``limits.stroke_mm``, ``limits.force_n``, below the controller's own interlock
    thresholds) on the channels that play the bench displacement and the plate force
    (UnboundRoleError when none does: nothing may run without them)."""
    return (
        ActuatorLinkLost(),
        ControllerInterlock(),
        SerialLinkLost(serial_timeout_s),
        WfsOverload(),
        displacement_limit(limits.stroke_mm, channels.name_of(Role.BENCH_DISPLACEMENT)),
        force_limit(limits.force_n, channels.name_of(Role.PLATE_FORCE)),
    )


def first_trip(interlocks: tuple[Interlock, ...], seen: Observation) -> tuple[str, str] | None:
    """(name, reason) of the first interlock that trips, or None."""
    for interlock in interlocks:
        reason = interlock.check(seen)
        if reason is not None:
            return interlock.name, reason
    return None
