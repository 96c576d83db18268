"""The small contracts through which the engine sees the bench's devices.

One protocol per capability, each method's meaning stated exactly, so that the actuator client over
Modbus, the WFS reader over a serial line, a simulated bench and a test fake are interchangeable.
Calls block until the device has answered (or raise a :class:`drivers.errors.LinkError`); none of
them may take longer than the link's documented timeouts.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from drivers.setpoints import AmplitudeUpdate, DriveSetpoint, DwellSetpoint, FrequencyUpdate, SweepSetpoint
from sequences import Prompt, Sweep


@dataclass(frozen=True)
class Notch:
    """The drive lowered by the response limit ``limit``: to ``amplitude_mm`` from ``start_hz`` to
    ``end_hz`` (a dwell's: its frequency)."""

    limit: str
    start_hz: float
    end_hz: float
    amplitude_mm: float


class Notching(Protocol):
    """Where a response would pass a response limit's notch level, the drive is lowered: a prediction
    of the responses of what stands on the bench (the dry run's model), with the conditions the
    sequence established (``tyre_pressure_bar``, ``wheel_fitted``, ...)."""

    def dwell(
        self, freq_hz: float, amplitude_mm: float, conditions: Mapping[str, Any], *, specimen: bool
    ) -> Notch | None:
        """The lowered amplitude of a dwell, or None when no response would pass its notch level;
        ``specimen`` False for a free run (nothing on the plate)."""
        ...

    def sweep(self, step: Sweep, conditions: Mapping[str, Any]) -> Notch | None:
        """The notch of a sweep (one band of its frequencies), or None."""
        ...


@dataclass(frozen=True)
class PlannedDrive:
    """A road replay's drive as the plan loaded and dry-ran it: the ``setpoint`` the controller
    plays, and ``record``: what the run records of it (its source and checksum, JSON-able)."""

    setpoint: DriveSetpoint
    record: Mapping[str, Any]


#: The dry run of one drive on the bench model against the post's limits: the refusals' texts, each
#: naming the drive's sample and the limit (empty: the drive may be uploaded).
DriveCheck = Callable[[DriveSetpoint], tuple[str, ...]]


@dataclass(frozen=True)
class PlannedIteration:
    """A drive iteration as the plan loaded it: the ``target`` of the matched response (its SI
    unit) at ``sample_rate_hz``, its 95 % half-width ``u95`` (None: the target states none), the
    broadband ``identification`` drive, the nominal ``plate_mass_kg`` the contact force is computed
    with on the rig, ``record``: what each of its runs records of it (the target's source and
    checksum, JSON-able), and ``check``: each drive's dry run (None until the plan has dry-run the
    sequence; a drive iteration without it is not run)."""

    target: np.ndarray
    u95: np.ndarray | None
    sample_rate_hz: float
    identification: DriveSetpoint
    plate_mass_kg: float
    record: Mapping[str, Any]
    check: DriveCheck | None = None


class ControllerStatus(Protocol):
    """What the engine reads back from the actuator controller."""

    @property
    def moving(self) -> bool:
        """True while the actuator is running or tapering."""
        ...

    @property
    def interlock_reason(self) -> str | None:
        """Why the controller is in interlock or e-stop (flags by name), None when it is not."""
        ...

    @property
    def sample_count(self) -> int:
        """The controller's own clock, in ticks since power-up."""
        ...


class StatusReadable(Protocol):
    def read_status(self) -> ControllerStatus:
        """Read the controller's state now (one request)."""
        ...


class Excitable(Protocol):
    def configure(self, setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint) -> None:
        """Check ``setpoint`` against the soft limits and write it; nothing moves yet. A drive plays
        what the controller holds: it must hold that drive (:meth:`DrivePlayable.load_drive`).

        Raises LimitError with nothing written when the setpoint lies outside the limits."""
        ...

    def start(self) -> None:
        """Start the last completely configured excitation (refused if the configure failed)."""
        ...

    def stop(self) -> None:
        """Take defensive action: taper the excitation out and ramp the mean back to rest.

        Safe to call in any state; returns once the controller accepted the stop (not at rest)."""
        ...


class AmplitudeAdjustable(Protocol):
    def update_amplitude(self, update: AmplitudeUpdate) -> None:
        """Give the sine dwell holding now a new amplitude, ramped; the dwell then holds its hold
        time again at it. LimitError (nothing written) outside the soft limits; CommandRejectedError
        when the controller refuses it (no dwell holding, beyond its own limits, no such registers).
        Only an actuator whose controller takes amplitude updates is asked."""
        ...


class FrequencyAdjustable(Protocol):
    def update_frequency(self, update: FrequencyUpdate) -> None:
        """Glide the sine dwell holding now to a new frequency, phase-continuously; the hold goes
        on. LimitError (nothing written) outside the soft limits; CommandRejectedError when the
        controller refuses it. Only an actuator whose controller takes frequency updates is asked."""
        ...


class DrivePlayable(Protocol):
    def load_drive(self, drive: DriveSetpoint) -> None:
        """Give the controller the drive to play (a file transfer over its link, as long as the drive
        needs), unless it holds that drive already; checked against what the controller received.
        LimitError (nothing written) outside the soft limits; CommandRejectedError when the
        controller plays no drive files or refuses the upload; DriveMismatchError when it reports
        another drive than the one sent. Only an actuator whose controller plays drive files is
        asked (its ``drive_files`` is true)."""
        ...


class EmergencyStoppable(Protocol):
    def estop(self) -> None:
        """Freeze the actuator at once (no taper). Must work from any thread at any moment."""
        ...


class HydraulicsControl(Protocol):
    def set_hydraulics(self, level: str) -> None:
        """Switch the hydraulic supply to ``"off"``, ``"low"`` or ``"high"`` pressure."""
        ...

    def reset_interlock(self) -> None:
        """Clear an interlock or a released e-stop; the controller returns to hydraulics low."""
        ...


class LinkSupervised(Protocol):
    def link_fault(self) -> str | None:
        """Why the link to the device can no longer be trusted (heartbeat writes failing, the
        connection dropped), or None while it is healthy. Once set it stays set until reconnected."""
        ...


class Actuator(StatusReadable, Excitable, EmergencyStoppable, HydraulicsControl, LinkSupervised, Protocol):
    """The actuator controller as the engine drives it."""


class SampleBlockLike(Protocol):
    """Consecutive WFS frames (``drivers.wfs_frame.FRAME_DTYPE``) with the gaps before some of them;
    ``arrived_s``: when the bytes that completed the block reached the port (monotonic s);
    ``unread_s``: how long the port went unread before that (a host stall when long)."""

    frames: np.ndarray
    gaps: tuple
    resyncs: tuple
    arrived_s: float
    unread_s: float


class SampleSubscription(Protocol):
    def get_all(self, timeout_s: float) -> SampleBlockLike | None:
        """Every frame that arrived since the last call, as one block, or None when none arrived
        within ``timeout_s`` seconds."""
        ...

    def close(self) -> None:
        """Stop receiving; the acquisition forgets this subscriber."""
        ...


class SampleSource(Protocol):
    def subscribe(self, *, lossless: bool, max_frames: int) -> SampleSubscription:
        """A new consumer of the frame stream. A lossless subscriber holds the acquisition back when
        it falls ``max_frames`` behind (the engine and the recorder must see every frame); a lossy
        one loses its oldest blocks instead (a live view) and never slows the others."""
        ...


class StreamControl(Protocol):
    def start_stream(self) -> None:
        """Start streaming frames; the frames' ``sample`` clock restarts at 0."""
        ...

    def stop_stream(self) -> None: ...

    def tare(self) -> None:
        """Zero the six load channels at the present load (the device's tare)."""
        ...


class LinkCounted(Protocol):
    def link_counters(self) -> dict[str, int]:
        """Cumulative link statistics by name (frames ok, missing, CRC rejects, reconnects, ...)."""
        ...

    def link_silence_s(self) -> float:
        """How long (s) no byte has arrived at the port, judged at the port: 0 while bytes wait there
        unread (the host is behind, not the link)."""
        ...


class CaptureLike(Protocol):
    """A triggered block of Fz: ``samples_n`` at ``rate_hz``, the trigger at ``pre_trigger_samples``."""

    samples_n: np.ndarray
    rate_hz: float
    pre_trigger_samples: int


class TriggeredCapture(Protocol):
    def arm_capture(self, trigger_level_n: float, pre_trigger_s: float, length_s: float) -> tuple[int, int]:
        """Arm a capture of Fz at the converter rate: a change beyond ``trigger_level_n`` from the
        present load fires it. Returns the block's samples and pre-trigger samples."""
        ...

    def wait_capture(self, timeout_s: float) -> CaptureLike:
        """The armed capture, once fired and received (LinkTimeoutError after ``timeout_s``)."""
        ...


class Acquisition(SampleSource, StreamControl, TriggeredCapture, LinkCounted, Protocol):
    """The WFS acquisition as the engine drives it."""


class Operator(Protocol):
    def answer(self, prompt: Prompt) -> object:
        """Ask the person at the bench ``prompt`` and return the answer, already checked with
        ``prompt.check_answer`` (ask again on a bad answer). May block for as long as the person
        takes. On the simulated bench the answer is also applied to the simulated world."""
        ...


@dataclass(frozen=True)
class RecordedDrive:
    """A complete run of a drive (a drive iteration's) as the campaign file holds it: its ``drive``
    attribute and its ``channels`` over the drive (standard names, sample 0 the drive's first)."""

    drive: Mapping[str, Any]
    channels: Mapping[str, np.ndarray]


class ResumePlan(Protocol):
    """What an interrupted campaign already holds, so that a resumed run skips it."""

    def run_complete(self, run_id: str) -> bool: ...

    def completed_points(self, run_id: str) -> set[int]: ...

    def recorded_samples(self, run_id: str) -> int:
        """The samples the run holds already (0 if it has none): its new samples follow them."""
        ...

    def recorded_drive(self, run_id: str) -> RecordedDrive | None:
        """A complete run's drive and its channels over it (None: no such complete run): a resumed
        drive iteration computes its next drive from the runs before."""
        ...


class RunGate(Protocol):
    """Consulted before each measurement run starts, with the bench at rest: what the runs before it
    established may forbid it (a free run whose plate mass is not to be trusted, before the runs
    that would use it). It may block until it knows (an analysis still under way)."""

    def __call__(self, run_id: str, kind: str) -> str | None:
        """None: the run may start; else why the sequence stops before it."""
        ...
