"""The dry run: before anything moves, predict every point of a sequence on the configured bench.

The bench model (:class:`~bench.models.setup.BenchSetup` of the configured kind, with the
specimen's tyre) gives each point's steady-state response in closed form, from the network's
frequency response at the point's operating point (harmonic balance for the non-linear tyre), not
from a time simulation. Predicted per point: peak displacement, velocity and acceleration of the
plate, the actuator's peak dynamic force (the plate force, plate mass included) and the WFS's
vertical load (dynamic amplitude plus the static load it carries at rest). A point beyond a limit
of :class:`~sequences.limits.BenchLimits` is refused, naming the point and the limit.

A road replay's drive is predicted sample by sample instead (:meth:`_World.predict_drive`): the
post's displacement (the drive, tapered, on its mean), its velocity and acceleration as the
controller plays it, and the plate and WFS forces of the bench model's frequency response to it;
a drive beyond a limit is refused naming its first sample beyond it (index and time) and the limit
(:class:`DriveRefusal`).

The dry run follows the sequence as the operator will: a pressure prompt's target sets the tyre
pressure of the points after it, removing or fitting the wheel (or driving the car off or on the
posts) changes what stands on the bench, and a free run always runs without the specimen.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from bench.config import BenchConfig
from bench.engine.contracts import DriveCheck, PlannedDrive
from bench.models.benches import TyreModel
from bench.models.parameters import (
    PAPER_TYRE_STIFFNESS_N_PER_M,
    DamperNonlinearity,
    Rig,
    Suspension,
    Tyre,
    TyreNonlinearity,
)
from bench.models.setup import BenchKind, BenchSetup, drive_density
from bench.models.taper import taper_envelope
from drivers.errors import LimitError
from drivers.setpoints import DriveSetpoint, equivalent_sine
from sequences.channels import Role
from sequences.errors import problems_text
from sequences.limits import peak_acceleration_m_s2, peak_velocity_mm_s
from sequences.runs import RigKind, RunKind
from sequences.steps import (
    ACTION_BENCH_KIND,
    DriveIteration,
    DwellGrid,
    FreeRun,
    HammerTest,
    Prompt,
    PromptAction,
    RoadReplay,
    Sequence,
    SineDwell,
    Sweep,
    TrackedDwell,
)

STANDARD_GRAVITY_M_S2 = 9.80665
#: Frequencies a sweep is evaluated at (log-spaced over its band, plus the model's resonances in it).
SWEEP_EVALUATION_POINTS = 120
#: ... and the band where an adaptive grid may add points, at each of its amplitudes.
REFINEMENT_EVALUATION_POINTS = 60
#: Frequencies the bench model's response to a drive is evaluated at (evenly from 0 to half the
#: drive's rate, interpolated onto its spectrum's bins): 0.12 Hz apart at 1 kHz, finer than the
#: half-power width of any mode of the bench (the wheel hop's, about 1.5 Hz, is the narrowest).
DRIVE_RESPONSE_POINTS = 4096
#: Rest after a drive over which its response is predicted (s): the wheel hop and the body decay.
DRIVE_RINGDOWN_S = 2.0

#: (prediction attribute, BenchLimits attribute, what it is, unit)
_CHECKS = (
    ("displacement_mm", "stroke_mm", "peak displacement", "mm"),
    ("velocity_mm_s", "velocity_mm_s", "peak velocity", "mm/s"),
    ("acceleration_m_s2", "acceleration_m_s2", "peak acceleration", "m/s^2"),
    ("actuator_force_n", "force_n", "actuator force", "N"),
    ("wfs_load_n", "wfs_force_n", "WFS load", "N"),
)


@dataclass(frozen=True)
class PointPrediction:
    """The predicted peaks of one point: a dwell, or a sweep or an adaptive grid's refinement band at
    one amplitude (then the largest over the band, each found at ``at_hz[quantity]``). ``setup`` is
    what stands on the bench ("shaker", "quarter_car", "free_run"); ``wfs_static_n`` is the part of
    ``wfs_load_n`` present at rest."""

    step_index: int
    point_index: int
    #: "dwell" | "sweep" | "refinement" (where an adaptive grid may add points) | "tracked" | "drive"
    kind: str
    freq_hz: float  # the dwell's frequency; a sweep's (a refinement band's) highest
    amplitude_mm: float
    setup: str
    pressure_bar: float | None
    displacement_mm: float
    velocity_mm_s: float
    acceleration_m_s2: float
    actuator_force_n: float
    wfs_load_n: float
    wfs_static_n: float
    at_hz: dict[str, float] = field(default_factory=dict)

    @property
    def label(self) -> str:
        what = {
            "dwell": f"{self.freq_hz:g} Hz",
            "sweep": f"sweep to {self.freq_hz:g} Hz",
            "refinement": f"points an adaptive grid may add up to {self.freq_hz:g} Hz",
            "tracked": f"tracked dwell up to {self.freq_hz:g} Hz",
            "drive": "road replay",
        }[self.kind]
        return f"steps[{self.step_index}] point {self.point_index} ({what}, {self.amplitude_mm:g} mm)"


@dataclass(frozen=True)
class Refusal:
    """A point beyond a limit: the point, the limit's name in BenchLimits, predicted and allowed."""

    point: PointPrediction
    limit: str
    quantity: str
    predicted: float
    allowed: float
    unit: str
    freq_hz: float

    def __str__(self) -> str:
        where = "" if self.point.kind == "dwell" else f" at {self.freq_hz:.4g} Hz"
        return (
            f"{self.point.label}: predicted {self.quantity} {self.predicted:.5g} {self.unit}{where} "
            f"is beyond the limit {self.limit} = {self.allowed:g} {self.unit}"
        )


@dataclass(frozen=True)
class ActionRefusal:
    """A prompt whose action cannot be done on the configured bench at all (a car driven onto the
    posts of a shaker): ``needs`` the bench kind it is done on, ``bench`` the configured one."""

    step_index: int
    prompt_id: str
    action: str
    needs: str
    bench: str

    def __str__(self) -> str:
        what = "prompt" if self.prompt_id != RoadReplay.kind else "step"
        return (
            f"steps[{self.step_index}] {what} {self.prompt_id!r}: {self.action} is done on a {self.needs}"
            f" bench, and the configured bench is a {self.bench} bench (give a {self.needs} bench"
            f" configuration with --bench: the simulated one is configs/simulated_{self.needs}.toml)"
        )


@dataclass(frozen=True)
class DriveRefusal:
    """A road replay's drive beyond a limit: the first sample beyond it (``sample``, its index in
    the drive; ``time_s`` from the drive's start), the limit's name in BenchLimits (``setpoint`` when
    the controller would refuse the drive itself: its rate, length, tapers), what, predicted and
    allowed."""

    step_index: int
    source: str
    sample: int
    time_s: float
    limit: str
    quantity: str
    predicted: float
    allowed: float
    unit: str

    def __str__(self) -> str:
        return f"steps[{self.step_index}] road replay ({self.source}): {self.detail()}"

    def detail(self) -> str:
        """The sample and the limit, without the step."""
        if self.limit == "setpoint":
            return self.quantity
        return (
            f"sample {self.sample} (t = {self.time_s:.4g} s): predicted {self.quantity}"
            f" {self.predicted:.5g} {self.unit} is beyond the limit {self.limit} ="
            f" {self.allowed:g} {self.unit}"
        )


Refusals = tuple["ActionRefusal | Refusal | DriveRefusal", ...]


class DryRunError(ValueError):
    """The dry run refused points; ``refusals`` lists them all, the first in the str."""

    def __init__(self, source: str, refusals: Refusals) -> None:
        self.refusals = refusals
        super().__init__(problems_text(f"{source}: {refusal}" for refusal in refusals))


@dataclass(frozen=True)
class DryRun:
    """Every point's prediction, and the refused ones."""

    source: str
    points: tuple[PointPrediction, ...]
    refusals: Refusals
    #: each drive iteration's dry run of the drives it will compute, by its step's index
    drive_checks: Mapping[int, DriveCheck] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.refusals

    def check(self) -> None:
        """Raise :class:`DryRunError` if any point was refused."""
        if self.refusals:
            raise DryRunError(self.source, self.refusals)


def dry_run(
    sequence: Sequence, config: BenchConfig, drives: Mapping[int, PlannedDrive] | None = None
) -> DryRun:
    """Predict every dwell, sweep and drive of ``sequence`` on the bench of ``config`` and check its
    limits. ``drives``: each road replay's drive by its step's index, as the plan loaded them
    (:func:`bench.replay_drive.load_drives`, which loads them when not given: SequenceError when a
    drive cannot be had)."""
    if drives is None and any(isinstance(step, RoadReplay) for step in sequence.steps):
        from bench.replay_drive import load_drives

        drives = load_drives(sequence)
    world = _World(config)
    points: list[PointPrediction] = []
    impossible: list[ActionRefusal | DriveRefusal] = []
    for index, step in enumerate(sequence.steps):
        if isinstance(step, Prompt):
            needs = ACTION_BENCH_KIND.get(step.action or "")
            if needs is not None and needs != config.kind:
                impossible.append(ActionRefusal(index, step.id, step.action, needs, config.kind))
            world.apply(step)
        elif step.run_kind is not None:
            predicted, refused = PREDICTIONS[step.run_kind](world, index, step, drives)
            points += predicted
            impossible += refused
    refusals = tuple(r for point in points if point.kind != "drive" for r in _refusals(point, config))
    return DryRun(sequence.source, tuple(points), (*impossible, *refusals), dict(world.drive_checks))


def _refusals(point: PointPrediction, config: BenchConfig) -> list[Refusal]:
    out = []
    for attribute, limit, quantity, unit in _CHECKS:
        predicted, allowed = getattr(point, attribute), getattr(config.limits, limit)
        if predicted > allowed:
            out.append(
                Refusal(
                    point,
                    limit,
                    quantity,
                    predicted,
                    allowed,
                    unit,
                    point.at_hz.get(attribute, point.freq_hz),
                )
            )
    return out


def tyre_at(pressure_bar: float, wheel_mass_kg: float) -> Tyre:
    """The paper's tyre at ``pressure_bar``: stiffness interpolated linearly between the pressures it
    reports (1.5 / 2.5 / 3.5 bar), held at the end values outside them."""
    pressures = sorted(PAPER_TYRE_STIFFNESS_N_PER_M)
    stiffness = float(
        np.interp(pressure_bar, pressures, [PAPER_TYRE_STIFFNESS_N_PER_M[p] for p in pressures])
    )
    return Tyre(stiffness_n_per_m=stiffness, wheel_mass_kg=wheel_mass_kg)


def bench_model(config: BenchConfig, pressure_bar: float, *, specimen: bool) -> BenchSetup:
    """The model of the configured bench with the tyre at ``pressure_bar``, or (``specimen``
    False) its plate alone."""
    rig = Rig(plate_mass_kg=config.masses.plate_kg)
    if not specimen:
        return BenchSetup(BenchKind.FREE_RUN, rig=rig)
    return BenchSetup(
        BenchKind.SHAKER if config.kind == RigKind.SHAKER else BenchKind.QUARTER_CAR,
        TyreModel(config.specimen.tyre_model),
        tyre_at(pressure_bar, config.masses.wheel_below_sensor_kg),
        sensor=config.wfs_sensor,
        rig=rig,
        nonlinearity=TyreNonlinearity() if config.specimen.nonlinear else None,
        suspension=Suspension(damper=DamperNonlinearity() if config.specimen.damper_nonlinear else None),
    )


#: The network output behind each role a response limit may watch.
RESPONSE_OUTPUTS = {Role.WFS_FZ: "f_wfs", Role.PLATE_FORCE: "f_plate", Role.HUB_ACCELERATION: "a_hub"}


def response_amplitudes(setup: BenchSetup, freq_hz: float, amplitude_m: float) -> dict[Role, float]:
    """The steady-state amplitude of each role's response (its channel's unit) to a sine of
    ``amplitude_m`` at ``freq_hz`` (the non-linear tyre linearised there); a role the setup has no
    output for (the WFS on a free run) responds 0."""
    network = setup.operating_network(freq_hz, amplitude_m)
    outputs = tuple(o for o in RESPONSE_OUTPUTS.values() if o in network.output_names)
    response = network.frequency_response(freq_hz, outputs=outputs)
    return {
        role: float(abs(response[output][0])) * amplitude_m if output in response else 0.0
        for role, output in RESPONSE_OUTPUTS.items()
    }


class _World:
    """What the dry run assumes stands on the bench, as the sequence's prompts change it."""

    def __init__(self, config: BenchConfig) -> None:
        self.config = config
        self.pressure_bar = config.specimen.tyre_pressure_bar
        self.specimen_on = config.specimen.wheel_fitted
        self._setups: dict[tuple[bool, float], BenchSetup] = {}
        self.drive_checks: dict[int, DriveCheck] = {}

    def apply(self, prompt: Prompt) -> None:
        if prompt.action == PromptAction.SET_TYRE_PRESSURE and isinstance(prompt.target, int | float):
            self.pressure_bar = float(prompt.target)
        elif prompt.action in (PromptAction.REMOVE_WHEEL, PromptAction.CAR_OFF_POSTS):
            self.specimen_on = False
        elif prompt.action in (PromptAction.FIT_WHEEL, PromptAction.CAR_ON_POSTS):
            self.specimen_on = True

    def setup(self, *, free_run: bool) -> BenchSetup:
        specimen = self.specimen_on and not free_run
        key = (specimen, self.pressure_bar if specimen else math.nan)
        if key not in self._setups:
            self._setups[key] = self._build(specimen)
        return self._setups[key]

    def _build(self, specimen: bool) -> BenchSetup:
        return bench_model(self.config, self.pressure_bar, specimen=specimen)

    def static_wfs_load_n(self, setup: BenchSetup) -> float:
        """The load the WFS carries at rest: on the four-post bench the weight above it, on the
        shaker the configured tyre preload; none without the specimen."""
        if setup.kind is BenchKind.QUARTER_CAR:
            above_kg = setup.suspension.unsprung_mass_above_kg + setup.suspension.body_mass_kg
            return above_kg * STANDARD_GRAVITY_M_S2
        if setup.kind is BenchKind.SHAKER:
            return self.config.specimen.preload_n
        return 0.0

    def _forces(self, setup: BenchSetup, freq_hz: float, amplitude_m: float) -> tuple[float, float]:
        """Peak plate force and dynamic WFS force (N) of a sine of ``amplitude_m`` at ``freq_hz``."""
        network = setup.operating_network(freq_hz, amplitude_m)
        outputs = ("f_plate", "f_wfs") if "f_wfs" in network.output_names else ("f_plate",)
        response = network.frequency_response(freq_hz, outputs=outputs)
        wfs = float(abs(response["f_wfs"][0])) * amplitude_m if "f_wfs" in response else 0.0
        return float(abs(response["f_plate"][0])) * amplitude_m, wfs

    def predict_dwell(self, setup: BenchSetup, index: int, j: int, dwell: SineDwell) -> PointPrediction:
        plate_n, wfs_n = self._forces(setup, dwell.freq_hz, dwell.amplitude_m)
        static_n = self.static_wfs_load_n(setup)
        return PointPrediction(
            step_index=index,
            point_index=j,
            kind="dwell",
            freq_hz=dwell.freq_hz,
            amplitude_mm=dwell.amplitude_mm,
            setup=setup.kind.value,
            pressure_bar=self.pressure_bar if setup.has_tyre else None,
            displacement_mm=abs(dwell.mean_mm) + dwell.amplitude_mm,
            velocity_mm_s=peak_velocity_mm_s(dwell.freq_hz, dwell.amplitude_mm),
            acceleration_m_s2=peak_acceleration_m_s2(dwell.freq_hz, dwell.amplitude_mm),
            actuator_force_n=plate_n,
            wfs_load_n=wfs_n + static_n if setup.has_tyre else 0.0,
            wfs_static_n=static_n,
        )

    def predict_refinement(
        self, setup: BenchSetup, index: int, j: int, grid: DwellGrid, nominal_mm: float
    ) -> PointPrediction:
        """The peaks of any point an adaptive grid may add at ``nominal_mm`` between its lowest and
        highest frequency (each at the amplitude the grid's crossover gives it), evaluated
        log-spaced and at the model's resonances: a refinement goes where the response is steep."""
        lo, hi = min(grid.freqs_hz), max(grid.freqs_hz)
        freqs = np.geomspace(lo, hi, REFINEMENT_EVALUATION_POINTS)
        resonances = setup.network().eigenfrequencies_hz()
        freqs = np.unique(np.r_[freqs, resonances[(resonances > lo) & (resonances < hi)]])
        dwells = [grid.dwell_at(float(f), nominal_mm) for f in freqs]
        forces = np.array([self._forces(setup, d.freq_hz, d.amplitude_m) for d in dwells])
        kinematics = np.array(
            [
                (
                    peak_velocity_mm_s(d.freq_hz, d.amplitude_mm),
                    peak_acceleration_m_s2(d.freq_hz, d.amplitude_mm),
                )
                for d in dwells
            ]
        )
        i_plate, i_wfs = int(np.argmax(forces[:, 0])), int(np.argmax(forces[:, 1]))
        i_v, i_a = int(np.argmax(kinematics[:, 0])), int(np.argmax(kinematics[:, 1]))
        static_n = self.static_wfs_load_n(setup)
        return PointPrediction(
            step_index=index,
            point_index=j,
            kind="refinement",
            freq_hz=hi,
            amplitude_mm=nominal_mm,
            setup=setup.kind.value,
            pressure_bar=self.pressure_bar if setup.has_tyre else None,
            displacement_mm=abs(grid.mean_mm) + max(d.amplitude_mm for d in dwells),
            velocity_mm_s=float(kinematics[i_v, 0]),
            acceleration_m_s2=float(kinematics[i_a, 1]),
            actuator_force_n=float(forces[i_plate, 0]),
            wfs_load_n=float(forces[i_wfs, 1]) + static_n if setup.has_tyre else 0.0,
            wfs_static_n=static_n,
            at_hz={
                "actuator_force_n": float(freqs[i_plate]),
                "wfs_load_n": float(freqs[i_wfs]),
                "velocity_mm_s": float(freqs[i_v]),
                "acceleration_m_s2": float(freqs[i_a]),
            },
        )

    def predict_sweep(self, setup: BenchSetup, index: int, sweep: Sweep) -> PointPrediction:
        """The sweep's steady-state peaks over its band: an upper estimate, since a sweep passes a
        resonance too quickly to build its full steady-state response."""
        lo, hi = sorted((sweep.start_hz, sweep.end_hz))
        freqs = np.geomspace(lo, hi, SWEEP_EVALUATION_POINTS)
        resonances = setup.network().eigenfrequencies_hz()
        freqs = np.unique(np.r_[freqs, resonances[(resonances > lo) & (resonances < hi)]])
        forces = np.array([self._forces(setup, f, sweep.amplitude_m) for f in freqs])
        i_plate, i_wfs = int(np.argmax(forces[:, 0])), int(np.argmax(forces[:, 1]))
        static_n = self.static_wfs_load_n(setup)
        return PointPrediction(
            step_index=index,
            point_index=0,
            kind="sweep",
            freq_hz=hi,
            amplitude_mm=sweep.amplitude_mm,
            setup=setup.kind.value,
            pressure_bar=self.pressure_bar if setup.has_tyre else None,
            displacement_mm=abs(sweep.mean_mm) + sweep.amplitude_mm,
            velocity_mm_s=peak_velocity_mm_s(hi, sweep.amplitude_mm),
            acceleration_m_s2=peak_acceleration_m_s2(hi, sweep.amplitude_mm),
            actuator_force_n=float(forces[i_plate, 0]),
            wfs_load_n=float(forces[i_wfs, 1]) + static_n if setup.has_tyre else 0.0,
            wfs_static_n=static_n,
            at_hz={"actuator_force_n": float(freqs[i_plate]), "wfs_load_n": float(freqs[i_wfs])},
        )

    def predict_drive(
        self, setup: BenchSetup, index: int, drive: DriveSetpoint
    ) -> tuple[PointPrediction, list[DriveRefusal]]:
        """A drive's peaks and its first sample beyond each limit: the post's displacement (the
        tapered drive on its mean), velocity and acceleration (its differences at its rate, as the
        controller's generator plays it: linear between samples; a sample's velocity is the one
        that reaches it from the sample before), and the plate and WFS forces (the
        bench model's response to it, computed over its spectrum, the tyre linearised at the
        drive's equivalent sine as the simulated plant takes it; the WFS with its static load)."""
        limits = self.config.limits
        try:
            drive.check(limits)
        except LimitError as exc:
            why = f"the controller would refuse it: {exc}"
            return self._drive_prediction(setup, index, drive, {}), [
                DriveRefusal(index, "", 0, 0.0, "setpoint", why, 0.0, 0.0, "")
            ]
        rate = drive.sample_rate_hz
        n = drive.n_samples
        t = np.arange(n) / rate
        envelope = taper_envelope(t, drive.duration_s, drive.taper_in_s, drive.taper_out_s)
        z_m = 1e-3 * drive.samples_mm.astype(float) * envelope
        velocity = np.r_[0.0, np.diff(z_m)] * rate  # from the sample before to this one
        acceleration = np.r_[0.0, np.diff(z_m, 2), 0.0] * rate**2
        forces = self._drive_forces(setup, z_m, rate)
        static_n = self.static_wfs_load_n(setup)
        series = {
            "displacement_mm": np.abs(1e3 * z_m + drive.mean_mm),
            "velocity_mm_s": 1e3 * np.abs(velocity),
            "acceleration_m_s2": np.abs(acceleration),
            "actuator_force_n": np.abs(forces["f_plate"]),
            "wfs_load_n": np.abs(forces["f_wfs"] + static_n) if "f_wfs" in forces else np.zeros(n),
        }
        refusals = []
        for attribute, limit, quantity, unit in _CHECKS:
            allowed = getattr(limits, limit)
            beyond = np.flatnonzero(series[attribute] > allowed)
            if beyond.size:
                k = int(beyond[0])
                predicted = float(series[attribute][k])
                where = (index, "", k, k / rate)
                refusals.append(DriveRefusal(*where, limit, quantity, predicted, allowed, unit))
        peaks = {attribute: float(np.max(values)) for attribute, values in series.items()}
        return self._drive_prediction(setup, index, drive, peaks), refusals

    def _drive_prediction(
        self, setup: BenchSetup, index: int, drive: DriveSetpoint, peaks: dict[str, float]
    ) -> PointPrediction:
        static_n = self.static_wfs_load_n(setup)
        return PointPrediction(
            step_index=index,
            point_index=0,
            kind="drive",
            freq_hz=drive.equivalent_frequency_hz,
            amplitude_mm=drive.peak_mm,
            setup=setup.kind.value,
            pressure_bar=self.pressure_bar if setup.has_tyre else None,
            displacement_mm=peaks.get("displacement_mm", abs(drive.mean_mm) + drive.peak_mm),
            velocity_mm_s=peaks.get("velocity_mm_s", 0.0),
            acceleration_m_s2=peaks.get("acceleration_m_s2", 0.0),
            actuator_force_n=peaks.get("actuator_force_n", 0.0),
            wfs_load_n=peaks.get("wfs_load_n", static_n if setup.has_tyre else 0.0),
            wfs_static_n=static_n,
        )

    def _drive_forces(self, setup: BenchSetup, z_m: np.ndarray, rate_hz: float) -> dict[str, np.ndarray]:
        """The plate (and WFS) force of the bench model under the displacement ``z_m`` (N), sample
        by sample: its spectrum (with :data:`DRIVE_RINGDOWN_S` of rest after it, so that the response
        does not wrap round) times the model's frequency response."""
        amplitude_m, freq_hz = equivalent_sine(z_m, rate_hz)
        network = setup.operating_network(freq_hz or 1.0, amplitude_m, drive_density(z_m, rate_hz))
        outputs = ("f_plate", "f_wfs") if "f_wfs" in network.output_names else ("f_plate",)
        size = z_m.size + round(DRIVE_RINGDOWN_S * rate_hz)
        bins = np.fft.rfftfreq(size, 1 / rate_hz)
        grid = np.linspace(0.0, rate_hz / 2, min(DRIVE_RESPONSE_POINTS, bins.size))
        response = network.frequency_response(grid, outputs=outputs)
        spectrum = np.fft.rfft(z_m, size)
        out = {}
        for name in outputs:
            h = np.interp(bins, grid, response[name].real) + 1j * np.interp(bins, grid, response[name].imag)
            out[name] = np.fft.irfft(spectrum * h, size)[: z_m.size]
        return out


#: What one measurement step adds to the dry run: its points' predictions and what the bench
#: cannot do of it.
Predicted = tuple[list[PointPrediction], list[ActionRefusal | DriveRefusal]]


def _predict_dwells(
    world: _World, index: int, step: SineDwell | DwellGrid, drives: Mapping[int, PlannedDrive] | None
) -> Predicted:
    """Each dwell at its steady state; an adaptive grid's refinement band at each amplitude."""
    return _dwell_points(world, index, step, free_run=False), []


def _predict_free_run(
    world: _World, index: int, step: FreeRun, drives: Mapping[int, PlannedDrive] | None
) -> Predicted:
    """The grid's dwells without the specimen, whatever the prompts before it did."""
    return _dwell_points(world, index, step.grid, free_run=True), []


def _dwell_points(
    world: _World, index: int, step: SineDwell | DwellGrid, *, free_run: bool
) -> list[PointPrediction]:
    setup = world.setup(free_run=free_run)
    dwells = step.dwells()
    points = [world.predict_dwell(setup, index, j, dwell) for j, dwell in enumerate(dwells)]
    if isinstance(step, DwellGrid) and step.adaptive is not None:
        points += [
            world.predict_refinement(setup, index, len(dwells) + a, step, nominal_mm)
            for a, nominal_mm in enumerate(step.amplitudes_mm)
        ]
    return points


def _predict_sweep(
    world: _World, index: int, step: Sweep, drives: Mapping[int, PlannedDrive] | None
) -> Predicted:
    return [world.predict_sweep(world.setup(free_run=False), index, step)], []


def _predict_tracked_dwell(
    world: _World, index: int, step: TrackedDwell, drives: Mapping[int, PlannedDrive] | None
) -> Predicted:
    """The search and the track, wherever its band may take it: as a sweep over that band."""
    top = step.search_end_hz * (1 + step.freq_band_pct / 100)
    band = Sweep(step.search_start_hz, top, step.track_s, step.amplitude_mm, mean_mm=step.mean_mm)
    prediction = world.predict_sweep(world.setup(free_run=False), index, band)
    return [replace(prediction, kind="tracked")], []


def _predict_road_replay(
    world: _World, index: int, step: RoadReplay, drives: Mapping[int, PlannedDrive] | None
) -> Predicted:
    """The drive sample by sample on a four-post bench; refused on any other."""
    config = world.config
    if config.kind != RigKind.FOUR_POST:
        return [], [ActionRefusal(index, step.kind, "a road replay", RigKind.FOUR_POST, config.kind)]
    assert drives is not None
    drive = drives[index]
    setpoint = replace(drive.setpoint, mean_mm=step.mean_mm)
    prediction, beyond = world.predict_drive(world.setup(free_run=False), index, setpoint)
    return [prediction], [replace(r, source=str(drive.record.get("source", ""))) for r in beyond]


def _predict_drive_iteration(
    world: _World, index: int, step: DriveIteration, drives: Mapping[int, object] | None
) -> Predicted:
    """The identification drive sample by sample on a four-post bench (refused on any other), and
    the check each later drive gets before its upload (:func:`drive_check`): those drives follow
    from the rig's response, unknown until it is measured."""
    config = world.config
    if config.kind != RigKind.FOUR_POST:
        return [], [ActionRefusal(index, step.kind, "a drive iteration", RigKind.FOUR_POST, config.kind)]
    planned = (drives or {}).get(index)
    setup = world.setup(free_run=False)
    world.drive_checks[index] = drive_check(world, setup, index, step)
    if planned is None:
        return [], []
    identification = replace(planned.identification, mean_mm=step.mean_mm)
    prediction, beyond = world.predict_drive(setup, index, identification)
    return [prediction], [replace(r, source="its identification drive") for r in beyond]


def drive_check(world: _World, setup: BenchSetup, index: int, step: DriveIteration) -> DriveCheck:
    """The dry run of one drive of a drive iteration, on the bench model of ``setup`` against the
    post's limits and the step's ``max_drive_mm``: each refusal's text naming its first sample
    beyond a limit (empty: the drive may be uploaded)."""

    def check(drive: DriveSetpoint) -> tuple[str, ...]:
        drive = replace(drive, mean_mm=step.mean_mm)
        _, beyond = world.predict_drive(setup, index, drive)
        texts = [r.detail() for r in beyond]
        if step.max_drive_mm:
            rate = drive.sample_rate_hz
            t = np.arange(drive.n_samples) / rate
            envelope = taper_envelope(t, drive.duration_s, drive.taper_in_s, drive.taper_out_s)
            over = np.flatnonzero(np.abs(drive.samples_mm * envelope) > step.max_drive_mm)
            if over.size:
                k = int(over[0])
                excursion_mm = abs(drive.samples_mm[k] * envelope[k])
                texts.append(
                    f"sample {k} (t = {k / rate:.4g} s): the drive's {excursion_mm:.5g} mm"
                    f" about its mean is beyond the limit max_drive_mm = {step.max_drive_mm:g} mm"
                )
        return tuple(texts)

    return check


def _predict_hammer(
    world: _World, index: int, step: HammerTest, drives: Mapping[int, PlannedDrive] | None
) -> Predicted:
    """Nothing moves: the operator strikes the sensor with the actuator at rest."""
    return [], []


#: The dry run of each kind of run (tests/test_run_kind_tables.py: every kind is here).
PREDICTIONS: dict[RunKind, Callable[..., Predicted]] = {
    RunKind.DWELL_GRID: _predict_dwells,
    RunKind.FREE_RUN: _predict_free_run,
    RunKind.SWEEP: _predict_sweep,
    RunKind.TRACKED_DWELL: _predict_tracked_dwell,
    RunKind.ROAD_REPLAY: _predict_road_replay,
    RunKind.DRIVE_ITERATION: _predict_drive_iteration,
    RunKind.HAMMER: _predict_hammer,
}
