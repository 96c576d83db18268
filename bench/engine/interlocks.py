"""Interlocks and limits: small checks that act when the bench leaves its safe envelope.

Each check looks at one :class:`Observation` (the newest samples, the excitation's frequency at
each, the controller's readback, the links' health) and returns the reason, or None; each has an
action (:class:`~sequences.response_limits.LimitAction`): indicate, hold, stop or interlock. The
engine checks every one after every block of samples and while it waits for samples
(:func:`trips`); the most severe that tripped acts (an interlock stops the actuator with a taper,
marks the run with its name and reason and keeps the data), the milder ones are recorded.
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
from sequences.response_limits import LimitAction, LimitProfile, ResponseLimit

#: The interlocks the engine trips itself, besides its checks: a host stall that lost frames
#: (docs/engine.md, *Host stalls*) and the excitation's watchdog (a start or an end the controller
#: did not make in time).
HOST_STALLED = "host stalled"
EXCITATION_WATCHDOG = "excitation watchdog"
ENGINE_INTERLOCKS = (HOST_STALLED, EXCITATION_WATCHDOG)

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
    empty when none arrived; ``freq_hz``: the excitation's frequency at each of those samples (None
    while none runs); ``controller``: the last readback, if one was taken;
    ``actuator_link_fault``: the Modbus link's fault, if any; ``seconds_without_samples``: how long no
    byte has arrived at the WFS port while the acquisition should be streaming (0 otherwise, and 0
    while bytes wait at the port unread: a busy host is not a silent link).
    """

    columns: Mapping[str, np.ndarray]
    controller: ControllerStatus | None = None
    actuator_link_fault: str | None = None
    seconds_without_samples: float = 0.0
    freq_hz: np.ndarray | None = None


class Interlock(Protocol):
    name: str
    action: LimitAction

    def check(self, seen: Observation) -> str | None:
        """The reason to stop now, or None."""
        ...


@dataclass(frozen=True)
class WfsOverload:
    """A load channel of the WFS (or one of its aux inputs) reports overload."""

    name: str = "WFS overload"
    action: LimitAction = LimitAction.INTERLOCK

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
    action: LimitAction = LimitAction.INTERLOCK

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


def displacement_limit(
    limit_mm: float, channel: str, action: LimitAction = LimitAction.INTERLOCK
) -> ChannelLimit:
    """|bench displacement| (``channel``, m) beyond ``limit_mm``."""
    return ChannelLimit("displacement limit", channel, limit_mm / 1e3, "m", action)


def force_limit(limit_n: float, channel: str, action: LimitAction = LimitAction.INTERLOCK) -> ChannelLimit:
    """|plate force| (``channel``, N) beyond ``limit_n``."""
    return ChannelLimit("force limit", channel, limit_n, "N", action)


@dataclass(frozen=True)
class ResponseLevel:
    """|channel| beyond one level of a response limit's profile at the excitation's frequency, while
    an excitation runs (``name``: the limit's name and the level, "wfs_fz alarm")."""

    name: str
    channel: str
    profile: LimitProfile
    unit: str
    action: LimitAction

    def check(self, seen: Observation) -> str | None:
        values = seen.columns.get(self.channel)
        if seen.freq_hz is None or values is None or len(values) != len(seen.freq_hz) or len(values) == 0:
            return None
        excess = np.abs(np.asarray(values, dtype=float)) / self.profile.at(seen.freq_hz)
        worst = int(np.argmax(excess))
        if excess[worst] <= 1:
            return None
        f = float(seen.freq_hz[worst])
        return (
            f"{self.channel} reached {abs(float(values[worst])):.4g} {self.unit} at {f:.4g} Hz, beyond"
            f" the {float(self.profile.at(f)):.4g} {self.unit} there"
        )


def response_levels(
    limit: ResponseLimit, channels: ChannelSet, unit: str
) -> tuple[ResponseLevel, ResponseLevel]:
    """The abort and the alarm level of ``limit`` on the channel playing its role."""
    channel = channels.name_of(limit.role)
    return (
        ResponseLevel(f"{limit.name} abort", channel, limit.abort, unit, limit.abort_action),
        ResponseLevel(f"{limit.name} alarm", channel, limit.alarm, unit, limit.alarm_action),
    )


@dataclass(frozen=True)
class ControllerInterlock:
    """The controller itself tripped (its limits, its watchdog) or was e-stopped."""

    name: str = "controller interlock"
    action: LimitAction = LimitAction.INTERLOCK

    def check(self, seen: Observation) -> str | None:
        if seen.controller is None:
            return None
        return seen.controller.interlock_reason


@dataclass(frozen=True)
class ActuatorLinkLost:
    """The Modbus link failed: the heartbeat cannot be trusted to reach the controller."""

    name: str = "actuator link lost"
    action: LimitAction = LimitAction.INTERLOCK

    def check(self, seen: Observation) -> str | None:
        return seen.actuator_link_fault


@dataclass(frozen=True)
class SerialLinkLost:
    """No WFS frame for ``timeout_s`` while the acquisition should stream."""

    timeout_s: float = 0.5
    name: str = "WFS link lost"
    action: LimitAction = LimitAction.INTERLOCK

    def check(self, seen: Observation) -> str | None:
        if seen.seconds_without_samples > self.timeout_s:
            return f"no WFS frame for {seen.seconds_without_samples:.2f} s (limit {self.timeout_s:g} s)"
        return None


def standard_interlocks(
    channels: ChannelSet,
    limits: BenchLimits,
    *,
    serial_timeout_s: float = 0.5,
    actions: Mapping[str, LimitAction] | None = None,
    response_limits: tuple[ResponseLimit, ...] = (),
) -> tuple[Interlock, ...]:
    """The checks every run is guarded by: the channel limits trip at the bench's stroke and plate
    force (``limits.stroke_mm``, ``limits.force_n``, below the controller's own interlock
    thresholds) on the channels that play the bench displacement and the plate force
    (UnboundRoleError when none does: nothing may run without them), each with its action from
    ``actions`` (``displacement_limit``, ``force_limit``, ``wfs_overload``; interlock by default);
    then the abort and alarm levels of every response limit."""
    act = dict(actions or {})
    units = {c.name: c.unit for c in channels}
    levels = [
        level
        for limit in response_limits
        for level in response_levels(limit, channels, units[channels.name_of(limit.role)])
    ]
    return (
        ActuatorLinkLost(),
        ControllerInterlock(),
        SerialLinkLost(serial_timeout_s),
        WfsOverload(action=act.get("wfs_overload", LimitAction.INTERLOCK)),
        displacement_limit(
            limits.stroke_mm,
            channels.name_of(Role.BENCH_DISPLACEMENT),
            act.get("displacement_limit", LimitAction.INTERLOCK),
        ),
        force_limit(
            limits.force_n, channels.name_of(Role.PLATE_FORCE), act.get("force_limit", LimitAction.INTERLOCK)
        ),
        *levels,
    )


def interlock_names(interlocks: tuple[Interlock, ...]) -> tuple[str, ...]:
    """Every name the engine can trip an interlock under with ``interlocks`` as its checks: each
    check's (a graded limit's too: its action may be an interlock), then the engine's own
    (:data:`ENGINE_INTERLOCKS`), each once, in that order. The actuator link lost that a command's
    link error ends a sequence on is :class:`ActuatorLinkLost`'s, a check of every bench."""
    return tuple(dict.fromkeys([*(interlock.name for interlock in interlocks), *ENGINE_INTERLOCKS]))


@dataclass(frozen=True)
class Trip:
    """A check that tripped: its name, why, and its action."""

    name: str
    reason: str
    action: LimitAction


def trips(interlocks: tuple[Interlock, ...], seen: Observation) -> list[Trip]:
    """Every check that trips on ``seen``, the most severe action first (in check order among equals)."""
    found = []
    for interlock in interlocks:
        reason = interlock.check(seen)
        if reason is not None:
            found.append(Trip(interlock.name, reason, getattr(interlock, "action", LimitAction.INTERLOCK)))
    return sorted(found, key=lambda trip: -trip.action.severity)
