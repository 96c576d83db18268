"""The step vocabulary of a test sequence, as plain frozen data.

A step says what the bench does, once: the engine derives the driver's setpoint from it, the
simulated world its waveform and the analysis its record. Lengths are in seconds and cycles,
amplitudes in mm as an operator states them (``amplitude_m`` for the physics). Every step class has
``kind``, its ``type`` in a sequence file, ``run_kind``, the kind of run it records (None: it
records none; a single sine dwell is recorded as a grid of one point), and
``estimated_duration_s``, the time the bench spends on it (operator prompts count 0 s: see
:attr:`Sequence.estimated_duration_with_operator_s`).

The steps hold whatever they are given; :func:`sequences.validation.validate` checks them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from enum import StrEnum
from typing import ClassVar

from sequences.errors import AnswerError
from sequences.runs import RigKind, RunKind

#: Stated times of the steps that do not excite: the controller's hydraulic pressure ramp, a tare
#: (the acquisition averages about a second at rest, plus the command round trips) and a slow move
#: to a new mean position.
HYDRAULICS_S = 3.0
TARE_S = 2.0
MEAN_POSITION_S = 2.0
#: Allowance for an operator's answer to one prompt (fitting a wheel, setting a pressure, a blow).
PROMPT_ALLOWANCE_S = 60.0
#: The crossover amplitude is rounded down to 0.1 um (this many decimals of a mm), far below any
#: servo's resolution, so a limited amplitude reads cleanly and never exceeds its maximum.
AMPLITUDE_DECIMALS = 4

GRID_ORDERS = ("amplitude-major", "frequency-major")
SWEEP_LAWS = ("linear", "log")
#: The ISO 8608 road classes a road replay generates (E-H are beyond any four-post bench's stroke).
ROAD_CLASSES = ("A", "B", "C", "D")
#: The spatial band (cycles/m) of a generated road by default: wavelengths from 20 m (longer ones
#: the car's body rides over and the posts' stroke cannot play) down to ISO 8608's 0.35 m.
ROAD_BAND_CYCLES_PER_M = (0.05, 2.83)


class HydraulicLevel(StrEnum):
    """The hydraulic pressure a ``hydraulics`` step switches to: off, low (positioning), high
    (testing)."""

    OFF = "off"
    LOW = "low"
    HIGH = "high"


class PromptAction(StrEnum):
    """What a prompt asks the operator to do to the bench, and what the simulated operator does with
    the answer in simulated mode."""

    SET_TYRE_PRESSURE = "set_tyre_pressure"
    REMOVE_WHEEL = "remove_wheel"
    FIT_WHEEL = "fit_wheel"
    CAR_ON_POSTS = "car_on_posts"
    CAR_OFF_POSTS = "car_off_posts"
    SET_DAMPER = "set_damper"
    STRIKE_HAMMER = "strike_hammer"


#: The members' words, as a sequence file spells them.
HYDRAULIC_LEVELS = tuple(level.value for level in HydraulicLevel)
ANSWER_TYPES = ("number", "confirm", "choice")
PROMPT_ACTIONS = tuple(action.value for action in PromptAction)
#: The bench on which a prompt action can be done at all (the others: on any bench): a wheel is
#: fitted to the shaker, a car driven onto the four posts.
ACTION_BENCH_KIND = {
    PromptAction.REMOVE_WHEEL: RigKind.SHAKER,
    PromptAction.FIT_WHEEL: RigKind.SHAKER,
    PromptAction.CAR_ON_POSTS: RigKind.FOUR_POST,
    PromptAction.CAR_OFF_POSTS: RigKind.FOUR_POST,
    PromptAction.SET_DAMPER: RigKind.FOUR_POST,
}
_YES = ("yes", "y", "ok", "done", "true")
_NO = ("no", "n", "false")


@dataclass(frozen=True, slots=True)
class SineDwell:
    """One sine dwell: taper in, settle, measure, taper out, at one frequency and amplitude.

    The settle and measure lengths are cycle counts (not necessarily whole) with a minimum in
    seconds, so low frequencies get enough cycles and high frequencies enough time. When a grid's
    velocity or acceleration maximum lowered the amplitude, ``requested_amplitude_mm`` is the grid's
    nominal amplitude and ``amplitude_limited_by`` names the maximum ("velocity"/"acceleration").
    """

    kind: ClassVar[str] = "sine_dwell"
    run_kind: ClassVar[RunKind | None] = RunKind.DWELL_GRID

    freq_hz: float
    amplitude_mm: float
    settle_cycles: float = 2.0
    settle_min_s: float = 0.2
    measure_cycles: float = 2.0
    measure_min_s: float = 1.0
    taper_in_s: float = 0.3
    taper_out_s: float = 0.3
    mean_mm: float = 0.0
    requested_amplitude_mm: float | None = None
    amplitude_limited_by: str | None = None

    @property
    def settle_s(self) -> float:
        return max(self.settle_cycles / self.freq_hz, self.settle_min_s)

    @property
    def measure_s(self) -> float:
        return max(self.measure_cycles / self.freq_hz, self.measure_min_s)

    @property
    def hold_s(self) -> float:
        """Full amplitude: the settling, then the measured part."""
        return self.settle_s + self.measure_s

    @property
    def duration_s(self) -> float:
        return self.taper_in_s + self.hold_s + self.taper_out_s

    @property
    def amplitude_m(self) -> float:
        return self.amplitude_mm * 1e-3

    @property
    def estimated_duration_s(self) -> float:
        return self.duration_s

    def dwells(self) -> tuple[SineDwell, ...]:
        """The dwells of the run it records: itself (a grid of one point)."""
        return (self,)


def crossover_amplitude_mm(
    freq_hz: float,
    amplitude_mm: float,
    max_velocity_mm_s: float | None,
    max_acceleration_m_s2: float | None,
) -> tuple[float, str | None]:
    """The amplitude a sine-test profile uses at ``freq_hz``: the nominal one, or less above the
    constant-velocity / constant-acceleration crossovers, ``min(A, v_max / w, a_max / w^2)``.

    Returns ``(amplitude_mm, limited_by)``, ``limited_by`` None when the nominal amplitude holds.
    """
    w = 2 * math.pi * freq_hz
    used, limited_by = amplitude_mm, None
    if max_velocity_mm_s is not None and max_velocity_mm_s / w < used:
        used, limited_by = max_velocity_mm_s / w, "velocity"
    if max_acceleration_m_s2 is not None and max_acceleration_m_s2 * 1e3 / w**2 < used:
        used, limited_by = max_acceleration_m_s2 * 1e3 / w**2, "acceleration"
    if limited_by is None:
        return amplitude_mm, None
    scale = 10**AMPLITUDE_DECIMALS
    return math.floor(used * scale) / scale, limited_by


@dataclass(frozen=True, slots=True)
class AdaptiveDwell:
    """Adaptive stepped sine on a dwell grid: dwells that end when settled and measured, and a grid
    refined where the response is steep (``adaptive`` table of a ``dwell_grid``; docs/sequences.md).

    The measured FRF point is ``output / (input + plate_mass_kg w^2 z)``: the WFS force over the
    contact force when ``input`` is the load cell under a plate of ``plate_mass_kg``. A dwell's hold
    lasts at least ``max(min_hold_cycles / f, min_hold_s)`` and at most ``max_hold_s``: it ends once
    the FRF point is steady within ``settle_tolerance`` (relative) and its standard uncertainty is at
    most ``magnitude_target_pct`` and ``phase_target_deg``. After the grid's frequencies, points are
    added (at most ``max_added_points`` per amplitude, none closer than ``min_spacing_hz`` to a
    measured one) until interpolating between neighbours errs by less than ``interpolation_db`` and
    ``interpolation_deg``.
    """

    output: str = "fz_wfs_n"
    input: str = "f_plate_n"
    plate_mass_kg: float = 0.0
    settle_tolerance: float = 0.005
    magnitude_target_pct: float = 0.5
    phase_target_deg: float = 0.5
    min_hold_cycles: float = 3.0
    min_hold_s: float = 0.3
    max_hold_s: float = 10.0
    interpolation_db: float = 0.5
    interpolation_deg: float = 5.0
    max_added_points: int = 12
    min_spacing_hz: float = 0.1

    def min_hold_at_s(self, freq_hz: float) -> float:
        """The shortest hold at ``freq_hz`` (s)."""
        return min(max(self.min_hold_cycles / freq_hz, self.min_hold_s), self.max_hold_s)


@dataclass(frozen=True, slots=True)
class DwellGrid:
    """Sine dwells over frequencies x amplitudes, all with the same timing.

    ``order`` "amplitude-major" runs every frequency at the first amplitude, then the next
    amplitude; "frequency-major" runs every amplitude at one frequency before the next. With
    ``max_velocity_mm_s`` / ``max_acceleration_m_s2`` the amplitude of a point is lowered above the
    crossover frequency (see :func:`crossover_amplitude_mm`) and each dwell records it. With
    ``adaptive`` the grid's frequencies are the coarse grid of an adaptive stepped sine
    (:class:`AdaptiveDwell`): its dwells end by their verdicts and the engine adds points.
    """

    kind: ClassVar[str] = "dwell_grid"
    run_kind: ClassVar[RunKind | None] = RunKind.DWELL_GRID

    freqs_hz: tuple[float, ...]
    amplitudes_mm: tuple[float, ...]
    order: str = "amplitude-major"
    settle_cycles: float = 2.0
    settle_min_s: float = 0.2
    measure_cycles: float = 2.0
    measure_min_s: float = 1.0
    taper_in_s: float = 0.3
    taper_out_s: float = 0.3
    mean_mm: float = 0.0
    max_velocity_mm_s: float | None = None
    max_acceleration_m_s2: float | None = None
    label: str = ""
    adaptive: AdaptiveDwell | None = None

    def _pairs(self) -> Iterator[tuple[float, float]]:
        if self.order == "frequency-major":
            return ((f, a) for f in self.freqs_hz for a in self.amplitudes_mm)
        return ((f, a) for a in self.amplitudes_mm for f in self.freqs_hz)

    def dwells(self) -> tuple[SineDwell, ...]:
        """The grid's dwells in run order, with the amplitude actually used."""
        return tuple(self.dwell_at(freq_hz, nominal_mm) for freq_hz, nominal_mm in self._pairs())

    def dwell_at(self, freq_hz: float, nominal_mm: float) -> SineDwell:
        """The grid's dwell at any frequency and nominal amplitude (a refinement adds such points)."""
        used_mm, limited_by = crossover_amplitude_mm(
            freq_hz, nominal_mm, self.max_velocity_mm_s, self.max_acceleration_m_s2
        )
        return SineDwell(
            freq_hz,
            used_mm,
            self.settle_cycles,
            self.settle_min_s,
            self.measure_cycles,
            self.measure_min_s,
            self.taper_in_s,
            self.taper_out_s,
            self.mean_mm,
            requested_amplitude_mm=nominal_mm if limited_by else None,
            amplitude_limited_by=limited_by,
        )

    @property
    def estimated_duration_s(self) -> float:
        """Fixed timing: every dwell's duration. Adaptive: the grid's dwells and the point budget
        at their shortest hold (a lower estimate: a dwell lasts until its verdicts)."""
        if self.adaptive is None:
            return sum(d.duration_s for d in self.dwells())
        a = self.adaptive
        tapers_s = self.taper_in_s + self.taper_out_s
        coarse_s = sum(tapers_s + a.min_hold_at_s(d.freq_hz) for d in self.dwells())
        added_s = len(self.amplitudes_mm) * a.max_added_points * (tapers_s + a.min_hold_s)
        return coarse_s + added_s


@dataclass(frozen=True, slots=True)
class FreeRun:
    """The grid's dwells with no wheel on the bench: the load cell sees only the plate (m_comp)."""

    kind: ClassVar[str] = "free_run"
    run_kind: ClassVar[RunKind | None] = RunKind.FREE_RUN

    grid: DwellGrid

    def dwells(self) -> tuple[SineDwell, ...]:
        return self.grid.dwells()

    @property
    def estimated_duration_s(self) -> float:
        return self.grid.estimated_duration_s


@dataclass(frozen=True, slots=True)
class Sweep:
    """A sine sweep from ``start_hz`` to ``end_hz``; ``duration_s`` includes the tapers, as the
    controller's ``sweep_duration_s`` register does."""

    kind: ClassVar[str] = "sweep"
    run_kind: ClassVar[RunKind | None] = RunKind.SWEEP

    start_hz: float
    end_hz: float
    duration_s: float
    amplitude_mm: float
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0
    law: str = "linear"
    mean_mm: float = 0.0
    label: str = ""

    @property
    def amplitude_m(self) -> float:
        return self.amplitude_mm * 1e-3

    @property
    def max_freq_hz(self) -> float:
        return max(self.start_hz, self.end_hz)

    @property
    def estimated_duration_s(self) -> float:
        return self.duration_s


@dataclass(frozen=True, slots=True)
class TrackedDwell:
    """A resonance found and dwelt on while it is tracked by phase (a tyre warming up moves it).

    **Search**: sine dwells at ``search_points`` frequencies evenly from ``search_start_hz`` to
    ``search_end_hz`` at ``amplitude_mm``, each ended by an adaptive dwell's verdicts (settled and
    measured), measure the ratio ``output / (input + plate_mass_kg w^2 z)`` (F_WFS / F_contact with
    the load cell under a plate of that mass; the hub acceleration over the post displacement with
    ``input`` the displacement and no plate mass). A single-mode fit through the largest point and
    its neighbours gives the resonance frequency, the ratio's peak and the damping ratio.
    **Track**: one dwell at the resonance for ``track_s`` (or ``track_cycles`` cycles when given):
    every ``update_s`` the ratio's phase is compared with its phase at the resonance, the resonance
    frequency estimated from the difference (the mode's phase slope) and the drive moved there.
    **Stop rules**: the tracked resonance leaving ``freq_band_pct`` of the one found, or the ratio's
    magnitude leaving ``ratio_band_pct`` of the one found, ends the track with the reason.
    """

    kind: ClassVar[str] = "tracked_dwell"
    run_kind: ClassVar[RunKind | None] = RunKind.TRACKED_DWELL

    search_start_hz: float
    search_end_hz: float
    amplitude_mm: float
    search_points: int = 8
    output: str = "fz_wfs_n"
    input: str = "f_plate_n"
    plate_mass_kg: float = 0.0
    track_s: float = 30.0
    track_cycles: float | None = None
    update_s: float = 0.5
    freq_band_pct: float = 5.0
    ratio_band_pct: float = 50.0
    taper_in_s: float = 0.3
    taper_out_s: float = 0.3
    mean_mm: float = 0.0
    label: str = ""

    def search_freqs_hz(self) -> tuple[float, ...]:
        """The search's frequencies, evenly spaced, both ends included."""
        n = max(int(self.search_points), 2)
        step = (self.search_end_hz - self.search_start_hz) / (n - 1)
        return tuple(round(self.search_start_hz + i * step, 6) for i in range(n))

    def search_plan(self) -> AdaptiveDwell:
        """The search dwells' verdicts: settled and measured to the adaptive dwell's default targets."""
        return AdaptiveDwell(output=self.output, input=self.input, plate_mass_kg=self.plate_mass_kg)

    @property
    def track_length_s(self) -> float:
        """The track's length: ``track_s``, or ``track_cycles`` at the search band's middle."""
        if self.track_cycles is None:
            return self.track_s
        return self.track_cycles / (0.5 * (self.search_start_hz + self.search_end_hz))

    @property
    def estimated_duration_s(self) -> float:
        """The search at its dwells' shortest hold, then the track, with every taper."""
        plan, tapers_s = self.search_plan(), self.taper_in_s + self.taper_out_s
        search_s = sum(tapers_s + plan.min_hold_at_s(f) for f in self.search_freqs_hz())
        return search_s + tapers_s + self.track_length_s


@dataclass(frozen=True, slots=True)
class RoadReplay:
    """A displacement drive played on the four-post bench's post: a drive file, or a generated road.

    **A drive file** (``file``, relative to the sequence file's folder): a CSV file (a time column
    and a displacement column with their units; ``time_column`` and ``channel`` name them, by
    default the first column and the only other one) or an MTS RPC III time history (``channel``
    names its channel, by default the only one). **A generated road** (``road_class``, A-D):
    ISO 8608's class driven at ``speed_km_h`` for ``duration_s``, sampled at ``sample_rate_hz``,
    seeded by ``seed``, over the spatial band ``band_cycles_per_m``. Either way the drive is played
    on ``mean_mm``, tapered in and out by raised cosines inside its length (``taper_in_s``,
    ``taper_out_s``). For a drive file ``duration_s`` may cut it: its first ``duration_s`` seconds
    (0: the whole file).
    """

    kind: ClassVar[str] = "road_replay"
    run_kind: ClassVar[RunKind | None] = RunKind.ROAD_REPLAY

    file: str = ""
    channel: str = ""
    time_column: str = ""
    road_class: str = ""
    speed_km_h: float = 0.0
    duration_s: float = 0.0
    seed: int = 0
    sample_rate_hz: float = 1000.0
    band_cycles_per_m: tuple[float, float] = ROAD_BAND_CYCLES_PER_M
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0
    mean_mm: float = 0.0
    label: str = ""

    @property
    def generated(self) -> bool:
        """A generated road (else a drive file)."""
        return bool(self.road_class)

    @property
    def estimated_duration_s(self) -> float:
        """The drive's length: a generated road's or the cut of a file; a whole file's length is
        known once the file is read (0 here)."""
        return float(self.duration_s)


#: What a drive iteration matches on the rig: the compensated contact force (the post's force less
#: its plate's inertia, as the analysis takes the contact force), the raw WFS force, the hub
#: acceleration, the post's force.
ITERATION_RESPONSES = ("contact_force", "wfs_force", "hub_acceleration", "post_force")
#: The spectral shapes of a drive iteration's identification drive: pink (density ~ 1/f over the
#: band) or shaped like the target's own density.
IDENTIFICATION_SHAPES = ("pink", "shaped")


@dataclass(frozen=True, slots=True)
class DriveIteration:
    """A drive iterated on the four-post bench until the rig's ``response`` matches a target
    (docs/sequences.md, *Drive iteration*).

    **The target** (``target``, relative to the sequence file's folder): a compensated road
    measurement written by ``wfsbench compensate`` (HDF5: its contact force and 95 % band), or a
    channel of a CSV, MDF4 or RPC III file (``target_channel``, in ``target_unit``: by default the
    unit the file states; a CSV file's time column ``time_column``, by default its first), cut to
    its first ``duration_s`` (0: whole). **The response** matched: ``contact_force`` (default),
    ``wfs_force``, ``hub_acceleration`` or ``post_force``.

    **The method**: the rig identified in ``band_hz`` with a broadband drive (``identification``:
    ``pink`` or ``shaped``, ``identification_rms_mm`` for ``identification_s``, seeded by
    ``identification_seed``), its coherence-weighted inverse regularised by ``regularisation``
    (relative to the FRF's peak power), the first drive from the inverse, then corrections with
    ``gain`` (0 < gain < 1). Every drive is dry-run against the post's limits and ``max_drive_mm``
    (0: the stroke) before upload. **Judged** in ``error_band_hz`` (inside ``band_hz``: the error's
    edge is not the inverse's) over the drive's hold less ``settle_s`` at each end (the tapers'
    transients). **Stops** when the rms error is below ``rms_error_pct`` % of the target's rms and
    (a target with a band) at least ``in_band_pct`` % of the samples are inside its 95 % band, or
    after ``max_iterations``. Damage ratios use the S-N exponent ``sn_exponent``. Drives are tapered
    by ``taper_in_s`` / ``taper_out_s`` and played on ``mean_mm``.
    """

    kind: ClassVar[str] = "drive_iteration"
    run_kind: ClassVar[RunKind | None] = RunKind.DRIVE_ITERATION

    target: str = ""
    target_channel: str = ""
    target_unit: str = ""
    time_column: str = ""
    response: str = "contact_force"
    duration_s: float = 0.0
    band_hz: tuple[float, float] = (0.3, 45.0)
    error_band_hz: tuple[float, float] = (0.5, 30.0)
    settle_s: float = 0.5
    identification: str = "pink"
    identification_rms_mm: float = 0.5
    identification_s: float = 20.0
    identification_seed: int = 1
    regularisation: float = 1e-5
    gain: float = 0.9
    max_iterations: int = 6
    rms_error_pct: float = 5.0
    in_band_pct: float = 90.0
    sn_exponent: float = 5.0
    max_drive_mm: float = 0.0
    taper_in_s: float = 0.5
    taper_out_s: float = 0.5
    mean_mm: float = 0.0
    label: str = ""

    @property
    def estimated_duration_s(self) -> float:
        """The identification and every iteration at the target's cut (a whole file's length is
        known once the file is read: the iterations count 0 s here then)."""
        return float(self.identification_s) + self.max_iterations * float(self.duration_s)


@dataclass(frozen=True, slots=True)
class HammerTest:
    """Hammer blows on the bare sensor, each caught by a triggered capture of the WFS acquisition.

    ``capture_s`` is the whole captured block, ``pre_trigger_s`` of it before the trigger.
    """

    kind: ClassVar[str] = "hammer"
    run_kind: ClassVar[RunKind | None] = RunKind.HAMMER

    trigger_level_n: float
    pre_trigger_s: float = 0.02
    capture_s: float = 0.3
    blows: int = 1

    def strike_prompt(self, blow: int) -> Prompt:
        """The prompt that asks for blow number ``blow`` (1-based) once the capture is armed."""
        return Prompt(
            id=f"strike_{blow}",
            text=f"Strike the sensor with the hammer (blow {blow} of {self.blows})",
            answer="confirm",
            action=PromptAction.STRIKE_HAMMER,
        )

    @property
    def estimated_duration_s(self) -> float:
        return self.blows * self.capture_s


@dataclass(frozen=True, slots=True)
class Prompt:
    """A question to the operator, e.g. "set the tyre pressure to 2.5 bar" answered with the
    pressure read on the gauge.

    ``answer`` is "number" (within ``minimum``..``maximum``, in ``unit``), "confirm" or "choice"
    (one of ``choices``). ``action`` names what the simulated operator does with the answer in
    simulated mode (:data:`PROMPT_ACTIONS`); ``target`` is the value asked for (2.5 for "set
    2.5 bar"), which the dry run assumes.
    """

    kind: ClassVar[str] = "prompt"
    run_kind: ClassVar[RunKind | None] = None

    id: str
    text: str
    answer: str = "confirm"
    unit: str | None = None
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = ()
    action: str | None = None
    target: float | str | None = None

    def check_answer(self, value: object) -> float | str | bool:
        """The answer as its type (float, str or bool), or :class:`AnswerError` with what is allowed.
        Typed text is accepted as the terminal gives it: a number as text, a choice or yes / no in
        any case (a choice is returned as the prompt spells it)."""
        if self.answer == "number":
            number = _as_number(value)
            lo = -math.inf if self.minimum is None else self.minimum
            hi = math.inf if self.maximum is None else self.maximum
            unit = f" {self.unit}" if self.unit else ""
            if number is None or not lo <= number <= hi:
                raise AnswerError(f"{self.id}: {value!r} is not a number within {lo:g}..{hi:g}{unit}")
            return number
        if self.answer == "choice":
            # as yes and no, a choice is a word whatever its case; recorded as the prompt spells it
            match = [c for c in self.choices if isinstance(value, str) and c == value.strip()] or [
                c for c in self.choices if isinstance(value, str) and c.casefold() == value.strip().casefold()
            ]
            if len(match) != 1:
                raise AnswerError(f"{self.id}: {value!r} is not one of {list(self.choices)}")
            return match[0]
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.strip().lower() in _YES + _NO:
            return value.strip().lower() in _YES
        raise AnswerError(f"{self.id}: {value!r} is not a confirmation; answer yes or no")

    @property
    def estimated_duration_s(self) -> float:
        return 0.0


def _as_number(value: object) -> float | None:
    if isinstance(value, bool):
        return None
    if isinstance(value, str):
        try:
            value = float(value.strip())
        except ValueError:
            return None
    if not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


@dataclass(frozen=True, slots=True)
class Hydraulics:
    """Switch the hydraulic pressure: "off", "low" (positioning) or "high" (testing)."""

    kind: ClassVar[str] = "hydraulics"
    run_kind: ClassVar[RunKind | None] = None

    level: str

    @property
    def estimated_duration_s(self) -> float:
        return HYDRAULICS_S


@dataclass(frozen=True, slots=True)
class Tare:
    """Zero the WFS with the bench at rest."""

    kind: ClassVar[str] = "tare"
    run_kind: ClassVar[RunKind | None] = None

    @property
    def estimated_duration_s(self) -> float:
        return TARE_S


@dataclass(frozen=True, slots=True)
class MeanPosition:
    """Move the actuator to a new static position (mm), e.g. to preload the tyre."""

    kind: ClassVar[str] = "mean_position"
    run_kind: ClassVar[RunKind | None] = None

    mean_mm: float

    @property
    def estimated_duration_s(self) -> float:
        return MEAN_POSITION_S


Step = (
    SineDwell
    | DwellGrid
    | FreeRun
    | Sweep
    | TrackedDwell
    | RoadReplay
    | DriveIteration
    | HammerTest
    | Prompt
    | Hydraulics
    | Tare
    | MeanPosition
)
STEP_TYPES: dict[str, type] = {
    cls.kind: cls
    for cls in (
        SineDwell,
        DwellGrid,
        FreeRun,
        Sweep,
        TrackedDwell,
        RoadReplay,
        DriveIteration,
        HammerTest,
        Prompt,
        Hydraulics,
        Tare,
        MeanPosition,
    )
}
#: The steps that record a run.
MEASUREMENT_TYPES = tuple(cls for cls in STEP_TYPES.values() if cls.run_kind is not None)


def step_fields(step: Step) -> dict[str, object]:
    """The step as flat named values, as in a sequence file (``type`` first; a free run's grid
    fields inline; unset optional values left out): for a run's record and for writing files."""
    inner = step.grid if isinstance(step, FreeRun) else step
    out: dict[str, object] = {"type": step.kind}
    for f in fields(inner):
        value = getattr(inner, f.name)
        if isinstance(value, AdaptiveDwell):
            value = {g.name: getattr(value, g.name) for g in fields(value)}
        if value is not None and value != () and not (f.name == "label" and value == ""):
            out[f.name] = list(value) if isinstance(value, tuple) else value
    return out


@dataclass(frozen=True, slots=True)
class Sequence:
    """A named list of steps; ``source`` is the file it came from (or ``<script>``); ``metadata``:
    the test metadata its ``[metadata]`` table gives (only the fields given, :mod:`sequences.metadata`)."""

    name: str
    description: str
    steps: tuple[Step, ...]
    source: str = "<script>"
    metadata: Mapping[str, str] = field(default_factory=dict)

    @property
    def estimated_duration_s(self) -> float:
        """The bench's time: every step's estimate, prompts counted 0 s."""
        return sum(step.estimated_duration_s for step in self.steps)

    @property
    def estimated_duration_with_operator_s(self) -> float:
        """The bench's time plus :data:`PROMPT_ALLOWANCE_S` per prompt and per hammer blow."""
        answers = sum(
            1 if isinstance(s, Prompt) else s.blows if isinstance(s, HammerTest) else 0 for s in self.steps
        )
        return self.estimated_duration_s + answers * PROMPT_ALLOWANCE_S

    def measurement_steps(self) -> tuple[Step, ...]:
        """The steps that record data (dwells, grids, free runs, sweeps, tracked dwells, road
        replays, hammer tests), in order."""
        return tuple(s for s in self.steps if isinstance(s, MEASUREMENT_TYPES))

    def points(self) -> int:
        """Measured points: one per dwell, per sweep, per road replay, per hammer blow, and a
        tracked dwell's search dwells and its track."""
        count = 0
        for step in self.measurement_steps():
            if isinstance(step, DwellGrid | FreeRun):
                count += len(step.dwells())
            elif isinstance(step, TrackedDwell):
                count += len(step.search_freqs_hz()) + 1  # the search's dwells, then the track
            elif isinstance(step, HammerTest):
                count += step.blows
            else:
                count += 1
        return count
