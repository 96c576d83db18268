"""The bench's recorded channels and the roles they play, declared once for every layer.

A *channel* is one recorded column of a run: its name (unit in the name: ``f_plate_n``), unit, what
it is, on-disk dtype and the *role* it plays. A role is what the engine, the interlocks and the
analysis need a channel for: the bench's displacement (amplitude control, excitation spans, the
displacement interlock), the plate's force (the force interlock, the contact force), the WFS's
vertical force, the hub's acceleration. A lab names its channels as it likes; the bench
configuration binds each role to one of them once, and everything above reads the role's channel
through that binding (:class:`ChannelSet`).

Each role has a *standard name*: the name the simulated bench records it under, the name the
analysis's records use, and the name a sequence file may use for the role's channel on any bench
(an adaptive grid's ``output = "fz_wfs_n"``). A file recorded under a lab's names carries each
channel's role, so the analysis finds the role's channel whatever it is called.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Iterator
from dataclasses import dataclass


class Role(enum.StrEnum):
    """What a recorded channel is for the bench."""

    BENCH_DISPLACEMENT = "bench_displacement"  # the bench's (post's) displacement, m
    PLATE_FORCE = "plate_force"  # the load cell under the bench's plate (the post's), N
    WFS_FZ = "wfs_fz"  # the WFS's vertical force in the wheel frame, N
    HUB_ACCELERATION = "hub_acceleration"  # vertical acceleration of the wheel hub, m/s^2
    HAMMER_FORCE = "hammer_force"  # the impact hammer's force, N
    SPARE = "spare"  # recorded, used by nothing of the bench's own


#: The aux-input roles a bench configuration may bind (the WFS's own loads are not wired to aux inputs).
AUX_ROLES = (Role.BENCH_DISPLACEMENT, Role.PLATE_FORCE, Role.HUB_ACCELERATION, Role.SPARE)
#: Roles every run needs bound: the engine measures amplitudes and spans on the displacement, and
#: the host's force interlock guards the plate force.
ENGINE_ROLES = (Role.BENCH_DISPLACEMENT, Role.PLATE_FORCE)


@dataclass(frozen=True, slots=True)
class Channel:
    """One recorded channel: ``name`` (unit in it), ``unit``, ``description`` for a reader of the
    file, on-disk ``dtype`` ("f4", "u4" or "u2") and the ``role`` it plays (None: bookkeeping such
    as the frame counter, or a load the bench does not single out)."""

    name: str
    unit: str
    description: str = ""
    dtype: str = "f4"
    role: Role | None = None


#: Each role's channel as the simulated bench records it: the standard name, unit and description.
STANDARD_CHANNELS: dict[Role, Channel] = {
    Role.BENCH_DISPLACEMENT: Channel(
        "z_base_m", "m", "bench (post) displacement", role=Role.BENCH_DISPLACEMENT
    ),
    Role.PLATE_FORCE: Channel(
        "f_plate_n", "N", "bench (post) plate force, load cell under the plate", role=Role.PLATE_FORCE
    ),
    Role.WFS_FZ: Channel(
        "fz_wfs_n", "N", "Fz in the non-rotating wheel frame, calibrated and tared", role=Role.WFS_FZ
    ),
    Role.HUB_ACCELERATION: Channel(
        "a_hub_m_s2", "m/s^2", "hub acceleration, vertical", role=Role.HUB_ACCELERATION
    ),
    Role.HAMMER_FORCE: Channel("f_hammer_n", "N", "impact hammer force", role=Role.HAMMER_FORCE),
}


def standard_name(role: Role) -> str:
    """The name the analysis and sequence files use for ``role``'s channel (``z_base_m``)."""
    return STANDARD_CHANNELS[role].name


def role_of_standard_name(name: str) -> Role | None:
    """The role whose standard name ``name`` is, or None."""
    return next((role for role, channel in STANDARD_CHANNELS.items() if channel.name == name), None)


@dataclass(frozen=True, slots=True)
class AuxInput:
    """What one analog input of the WFS acquisition (aux0..aux3) carries: the ``channel`` it is
    recorded as (its role among them) and ``scale``, the channel's unit per unit of the frame's value."""

    channel: Channel
    scale: float = 1.0


#: The aux inputs as the simulated bench wires them: displacement, plate force, hub acceleration, spare.
DEFAULT_AUX_INPUTS = (
    AuxInput(STANDARD_CHANNELS[Role.BENCH_DISPLACEMENT]),
    AuxInput(STANDARD_CHANNELS[Role.PLATE_FORCE]),
    AuxInput(STANDARD_CHANNELS[Role.HUB_ACCELERATION]),
    AuxInput(Channel("aux3", "V", "spare input", role=Role.SPARE)),
)


class UnboundRoleError(LookupError):
    """A role something needs is played by none of the bench's channels."""

    def __init__(self, role: Role, names: Iterable[str]) -> None:
        self.role = role
        super().__init__(f"no recorded channel has the role {role.value} (the channels: {', '.join(names)})")


@dataclass(frozen=True)
class ChannelSet:
    """The channels one bench records, in recording order, and the role each plays."""

    channels: tuple[Channel, ...]

    def __iter__(self) -> Iterator[Channel]:
        return iter(self.channels)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.channels)

    def bound(self, role: Role) -> bool:
        return any(c.role is role for c in self.channels)

    def name_of(self, role: Role) -> str:
        """The name of the channel playing ``role``; UnboundRoleError when none does."""
        for channel in self.channels:
            if channel.role is role:
                return channel.name
        raise UnboundRoleError(role, self.names)

    def resolve(self, name: str) -> str | None:
        """The recorded channel ``name`` means: itself when recorded, else the channel of the role
        whose standard name it is (``f_plate_n`` on a bench that calls its load cell
        ``f_loadcell_n``); None when it means no channel of this bench."""
        if name in self.names:
            return name
        role = role_of_standard_name(name)
        if role is not None and self.bound(role):
            return self.name_of(role)
        return None
