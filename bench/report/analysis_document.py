"""A campaign's analysis as the public JSON document (schema ``wfs-bench-analysis``,
docs/analysis-json.md): one frozen dataclass per JSON object, its field names the object's keys.

Each type's ``of`` builds it from the analysis's result types, so the JSON is written from the
types (:func:`~bench.report.json_out.document_text`, laid out by :mod:`bench.store.typed`) and read
back into them (:func:`~bench.report.json_out.read_analysis_json`): a reader, the index's rows among
them, asks for attributes, not for keys. SI units throughout, named in the keys (``_hz``, ``_kg``,
``_m``, ``_n_per_m``, ``_ns_per_m``, ``_s``); ratios and damping ratios are plain numbers. A number
the data does not give is None (``null``), never a guess, and never NaN or infinity: every number a
fit or a measurement gives goes through :func:`_number`.

:data:`VERSION` is raised with every change to these types, a key added too (the typed reader reads its
own version only; docs/analysis-json.md says which versions only add keys) (2: the
quarter car's tyre loss became a friction force; 3: the document is made and read by these types).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from bench.analysis.campaign import CampaignAnalysis, RunAnalysis, SensorSource
from bench.analysis.drive_iteration import IterationResult, by_step
from bench.analysis.dwell import DwellFit
from bench.analysis.flags import Flag, flags_of
from bench.analysis.frf import ValidBand
from bench.analysis.hammer import HammerResult
from bench.analysis.lsq import Z95
from bench.analysis.quarter_car_fit import QuarterCarFit
from bench.analysis.repeats import RepeatSpread
from bench.analysis.road_replay import RoadReplayResult
from bench.analysis.road_validation import ERROR_BAND_HZ, OCTAVE_CENTRES_HZ, ForceErrors
from bench.analysis.runs import (
    FourPostResult,
    FreeRunResult,
    ShakerAmplitudeResult,
    ShakerCampaignResult,
    ShakerRatiosResult,
)
from bench.analysis.tyre_fit import AmplitudeRow, RatioPeak, TyreFit
from bench.report.text import free_run_lines
from sequences.metadata import METADATA_FIELDS

SCHEMA = "wfs-bench-analysis"
VERSION = 3


def _number(value: float) -> float | None:
    """A finite float, or None: the JSON holds no NaN or infinity."""
    value = float(value)
    return value if math.isfinite(value) else None


def _numbers(values: Mapping[str, float]) -> dict[str, float | None]:
    """Named numbers, each through :func:`_number`."""
    return {name: _number(v) for name, v in values.items()}


def _floats(values: Iterable[float]) -> tuple[float, ...]:
    """Frequencies and other numbers that are always finite, as plain floats."""
    return tuple(float(v) for v in values)


def _pair(values: Iterable[float]) -> tuple[float, float]:
    """A band's two ends (Hz) as plain floats."""
    low, high = values
    return float(low), float(high)


def _freq_range_hz(fits: tuple[DwellFit, ...]) -> tuple[float, float]:
    """The lowest and highest dwell frequency of ascending ``fits``."""
    return float(fits[0].freq_hz), float(fits[-1].freq_hz)


@dataclass(frozen=True)
class SequenceDoc:
    """A sequence whose runs the file holds: its ``name`` in the run ids and how many ``runs``."""

    name: str
    runs: int

    @classmethod
    def of(cls, sequence: tuple[str, int]) -> SequenceDoc:
        """From the analysis's (name, number of runs)."""
        name, runs = sequence
        return cls(name, int(runs))


@dataclass(frozen=True)
class GivenDoc:
    """The masses the configuration gives (kg), which the analysis takes as they are."""

    sensor_mass_kg: float
    wheel_mass_kg: float

    @classmethod
    def of(cls, analysis: CampaignAnalysis) -> GivenDoc:
        return cls(float(analysis.sensor_mass_kg), float(analysis.wheel_mass_kg))


@dataclass(frozen=True)
class SensorDoc:
    """The sensor model the later runs were analysed with, and where it comes from."""

    mass_kg: float
    eigenfrequency_hz: float
    damping_ratio: float
    from_hammer_test: bool
    source: str

    @classmethod
    def of(cls, analysis: CampaignAnalysis) -> SensorDoc:
        k = analysis.knowledge
        return cls(
            mass_kg=float(k.sensor.mass_kg),
            eigenfrequency_hz=float(k.sensor.eigenfrequency_hz),
            damping_ratio=float(k.sensor.damping_ratio),
            from_hammer_test=k.sensor_source == SensorSource.HAMMER_TEST,
            source=str(k.sensor_source),
        )


@dataclass(frozen=True)
class HammerDoc:
    """The hammer test of the bare sensor: its eigenfrequency, damping and the decay it used."""

    eigenfrequency_hz: float | None
    damped_frequency_hz: float | None
    damping_ratio_half_power: float | None
    damping_ratio_log_decrement: float | None
    stiffness_n_per_m: float | None
    damping_ns_per_m: float | None
    n_peaks: int
    decay_start_s: float
    decay_stop_s: float

    @classmethod
    def of(cls, result: HammerResult) -> HammerDoc:
        return cls(
            eigenfrequency_hz=_number(result.eigenfrequency_hz),
            damped_frequency_hz=_number(result.damped_frequency_hz),
            damping_ratio_half_power=_number(result.damping_ratio_half_power),
            damping_ratio_log_decrement=_number(result.damping_ratio_log_decrement),
            stiffness_n_per_m=_number(result.stiffness_n_per_m),
            damping_ns_per_m=_number(result.damping_ns_per_m),
            n_peaks=int(result.n_peaks),
            decay_start_s=float(result.decay_start_s),
            decay_stop_s=float(result.decay_stop_s),
        )


@dataclass(frozen=True)
class RepeatDoc:
    """A dwell measured more than once: how many repeats were combined, and per channel their
    relative rms spread against the spread their noise alone gives."""

    freq_hz: float
    n: int
    spread: dict[str, float | None]
    noise: dict[str, float | None]
    outside_noise: bool

    @classmethod
    def of(cls, repeat: RepeatSpread) -> RepeatDoc:
        return cls(
            freq_hz=float(repeat.freq_hz),
            n=int(repeat.n),
            spread=_numbers(repeat.spread),
            noise=_numbers(repeat.noise),
            outside_noise=bool(repeat.outside_noise),
        )

    @classmethod
    def all_of(cls, repeats: tuple[RepeatSpread, ...]) -> tuple[RepeatDoc, ...]:
        return tuple(cls.of(r) for r in repeats)


@dataclass(frozen=True)
class FreeRunDoc:
    """m_comp of a plate from its free run (or as configured: ``nominal``), its misfit and flags."""

    m_comp_kg: float | None
    m_comp_sigma_kg: float | None
    nominal: bool
    residual_rms_n_per_m: float | None
    residual_reduced_chi2: float | None
    n_points_used: int
    n_dwells: int
    freq_range_hz: tuple[float, float] | None
    flags: tuple[str, ...]
    repeats: tuple[RepeatDoc, ...]

    @classmethod
    def of(cls, result: FreeRunResult) -> FreeRunDoc:
        p = result.plate
        return cls(
            m_comp_kg=_number(p.mass_kg),
            m_comp_sigma_kg=None if result.nominal else _number(p.sigma_kg),
            nominal=result.nominal,
            residual_rms_n_per_m=_number(p.residual_rms_n_per_m),
            residual_reduced_chi2=None if result.nominal else _number(p.reduced_chi2),
            n_points_used=int(p.n_points),
            n_dwells=len(result.fits),
            freq_range_hz=_freq_range_hz(result.fits) if result.fits else None,
            flags=tuple(flag.line for flag in flags_of(free_run_lines(result))),
            repeats=RepeatDoc.all_of(result.repeats),
        )


@dataclass(frozen=True)
class BandDoc:
    """A valid band: where it starts and ends (Hz), why, and the unreliable points it skips."""

    determined: bool
    lowest_hz: float | None
    upper_hz: float | None
    n_points: int
    starts_at: str
    limited_by: str
    skipped_hz: tuple[float, ...]
    amplitude_tolerance: float
    phase_tolerance_deg: float

    @classmethod
    def of(cls, band: ValidBand) -> BandDoc:
        return cls(
            determined=band.determined,
            lowest_hz=_number(band.lowest_hz) if band.n_points else None,
            upper_hz=_number(band.upper_hz) if band.determined else None,
            n_points=int(band.n_points),
            starts_at=band.starts_at,
            limited_by=band.limited_by,
            skipped_hz=_floats(band.skipped_hz),
            amplitude_tolerance=float(band.amplitude_tolerance),
            phase_tolerance_deg=float(band.phase_tolerance_deg),
        )


@dataclass(frozen=True)
class ModelFitDoc:
    """One tyre model fitted to an amplitude: its parameters with 95 % half-widths (by name, the
    unit in the name), those the data does not determine, and the fit's figures."""

    model: int
    values: dict[str, float | None]
    ci95: dict[str, float | None]
    undetermined: tuple[str, ...]
    converged: bool
    bic: float | None
    aic: float | None
    ratio_relative_rms: float | None

    @classmethod
    def of(cls, fit: TyreFit) -> ModelFitDoc:
        return cls(
            model=int(fit.model),
            values=_numbers(fit.values),
            ci95=_numbers(fit.ci95),
            undetermined=tuple(fit.undetermined),
            converged=bool(fit.converged),
            bic=_number(fit.bic),
            aic=_number(fit.aic),
            ratio_relative_rms=_number(fit.ratio_relative_rms),
        )


@dataclass(frozen=True)
class ModelPeakDoc:
    """The peak of the selected model's |F_WFS/F_contact| with its 95 % half-widths."""

    freq_hz: float | None
    freq_ci95_hz: float | None
    ratio: float | None
    ratio_ci95: float | None

    @classmethod
    def of(cls, peak: RatioPeak) -> ModelPeakDoc:
        return cls(
            freq_hz=_number(peak.freq_hz),
            freq_ci95_hz=_number(peak.freq_ci95_hz),
            ratio=_number(peak.height),
            ratio_ci95=_number(peak.height_ci95),
        )


@dataclass(frozen=True)
class LargestMeasuredDoc:
    """The largest reliable measured |F_WFS/F_contact| and where: a lower bound of the peak."""

    freq_hz: float
    ratio: float | None

    @classmethod
    def of(cls, result: ShakerAmplitudeResult) -> LargestMeasuredDoc:
        freq_hz, ratio = result.largest_measured_ratio
        return cls(float(freq_hz), _number(ratio))


@dataclass(frozen=True)
class AmplitudeDoc:
    """One excitation amplitude with a tyre fit: Models 1-3, the one selected and why, its peak,
    the valid bands, the compensator's design and the dwells left out."""

    amplitude_m: float
    n_dwells: int
    freq_range_hz: tuple[float, float]
    selected_model: int
    selection: str
    frequency_dependent_stiffness: bool
    hysteretic_damping: bool
    models: tuple[ModelFitDoc, ...]
    findings: tuple[str, ...]
    model_peak: ModelPeakDoc | None
    largest_measured: LargestMeasuredDoc
    valid_band_raw: BandDoc
    valid_band_compensated: BandDoc
    band_conditions: tuple[str, ...]
    plate_mass_tolerance_kg: float | None
    compensator_design_error: float | None
    compensator_band_hz: float
    unsettled: tuple[str, ...]
    rejected: tuple[str, ...]
    hub_acceleration_recorded: bool
    repeats: tuple[RepeatDoc, ...]

    @classmethod
    def of(cls, result: ShakerAmplitudeResult) -> AmplitudeDoc:
        ident = result.identification
        tolerance_kg = result.plate_mass_tolerance_kg
        return cls(
            amplitude_m=float(result.amplitude_m),
            n_dwells=len(result.fits),
            freq_range_hz=_freq_range_hz(result.fits),
            selected_model=int(ident.best),
            selection=ident.selection,
            frequency_dependent_stiffness=bool(ident.frequency_dependent_stiffness),
            hysteretic_damping=bool(ident.hysteretic_damping),
            models=tuple(ModelFitDoc.of(fit) for fit in ident.fits.values()),
            findings=tuple(ident.findings),
            model_peak=None if result.model_peak is None else ModelPeakDoc.of(result.model_peak),
            largest_measured=LargestMeasuredDoc.of(result),
            valid_band_raw=BandDoc.of(result.valid_band_raw),
            valid_band_compensated=BandDoc.of(result.valid_band_compensated),
            band_conditions=tuple(result.band_conditions),
            plate_mass_tolerance_kg=None if tolerance_kg is None else _number(tolerance_kg),
            compensator_design_error=_number(result.compensator.design_error),
            compensator_band_hz=float(result.compensator.band_hz),
            unsettled=tuple(result.unsettled),
            rejected=tuple(result.rejected),
            hub_acceleration_recorded=bool(result.hub_acceleration_recorded),
            repeats=RepeatDoc.all_of(result.repeats),
        )


@dataclass(frozen=True)
class RatioRowDoc:
    """One dwell of an amplitude without a tyre fit: the measured F_WFS/F_contact, its magnitude
    and phase with their 95 % half-widths, and whether the point is reliable."""

    freq_hz: float
    ratio: float | None
    ratio_ci95: float | None
    phase_deg: float | None
    phase_ci95_deg: float | None
    reliable: bool

    @classmethod
    def all_of(cls, result: ShakerRatiosResult) -> tuple[RatioRowDoc, ...]:
        """Every dwell's row; the half-widths from the ratio's complex standard uncertainty."""
        raw = result.frfs.wfs_per_contact
        half = Z95 * raw.sigma / np.sqrt(2)
        return tuple(
            cls(
                freq_hz=float(f),
                ratio=_number(abs(h)),
                ratio_ci95=_number(c),
                phase_deg=_number(np.degrees(np.angle(h))),
                phase_ci95_deg=_number(np.degrees(c / abs(h))),
                reliable=bool(ok),
            )
            for f, h, c, ok in zip(raw.freq_hz, raw.value, half, raw.reliable, strict=True)
        )


@dataclass(frozen=True)
class RatiosOnlyDoc:
    """An amplitude with too few reliable dwells for a tyre fit: why, and its measured ratios."""

    amplitude_m: float
    n_dwells: int
    freq_range_hz: tuple[float, float]
    why_no_fit: str
    ratios: tuple[RatioRowDoc, ...]
    valid_band_raw: BandDoc
    unsettled: tuple[str, ...]
    rejected: tuple[str, ...]
    hub_acceleration_recorded: bool
    repeats: tuple[RepeatDoc, ...]

    @classmethod
    def of(cls, result: ShakerRatiosResult) -> RatiosOnlyDoc:
        return cls(
            amplitude_m=float(result.amplitude_m),
            n_dwells=len(result.fits),
            freq_range_hz=_freq_range_hz(result.fits),
            why_no_fit=result.why,
            ratios=RatioRowDoc.all_of(result),
            valid_band_raw=BandDoc.of(result.valid_band_raw),
            unsettled=tuple(result.unsettled),
            rejected=tuple(result.rejected),
            hub_acceleration_recorded=bool(result.hub_acceleration_recorded),
            repeats=RepeatDoc.all_of(result.repeats),
        )


@dataclass(frozen=True)
class AmplitudeRowDoc:
    """Model 2 at one amplitude: its stiffness and equivalent damping, and their change against
    the smallest amplitude."""

    amplitude_m: float
    stiffness_n_per_m: float | None
    stiffness_ci95_n_per_m: float | None
    stiffness_change: float | None
    equivalent_damping_ns_per_m: float | None
    damping_change: float | None

    @classmethod
    def of(cls, row: AmplitudeRow) -> AmplitudeRowDoc:
        return cls(
            amplitude_m=float(row.amplitude_m),
            stiffness_n_per_m=_number(row.stiffness_n_per_m),
            stiffness_ci95_n_per_m=_number(row.stiffness_ci95_n_per_m),
            stiffness_change=_number(row.stiffness_change),
            equivalent_damping_ns_per_m=_number(row.equivalent_damping_ns_per_m),
            damping_change=_number(row.damping_change),
        )


@dataclass(frozen=True)
class ShakerPressureDoc:
    """One tyre pressure on the shaker: the models used, m_comp, each amplitude's identification
    (or measured ratios only) and Model 2's amplitude dependence (None with fewer than two)."""

    tyre_pressure_bar: float
    wheel_mass_kg: float
    sensor_eigenfrequency_hz: float
    sensor_damping_ratio: float
    free_run: FreeRunDoc
    amplitudes: tuple[AmplitudeDoc, ...]
    ratios_only: tuple[RatiosOnlyDoc, ...]
    amplitude_dependence: tuple[AmplitudeRowDoc, ...] | None

    @classmethod
    def of(cls, pressure_bar: float, result: ShakerCampaignResult) -> ShakerPressureDoc:
        dependence = result.amplitude_dependence
        return cls(
            tyre_pressure_bar=float(pressure_bar),
            wheel_mass_kg=float(result.wheel_mass_kg),
            sensor_eigenfrequency_hz=float(result.sensor.eigenfrequency_hz),
            sensor_damping_ratio=float(result.sensor.damping_ratio),
            free_run=FreeRunDoc.of(result.free_run),
            amplitudes=tuple(AmplitudeDoc.of(r) for r in result.amplitudes.values()),
            ratios_only=tuple(RatiosOnlyDoc.of(r) for r in result.ratios_only.values()),
            amplitude_dependence=None
            if dependence is None
            else tuple(AmplitudeRowDoc.of(row) for row in dependence.rows()),
        )


@dataclass(frozen=True)
class QuarterCarDoc:
    """The car above the sensor identified on the four-post bench: its parameters with 95 %
    half-widths (by name), what the data does not determine or was taken as given, and its modes."""

    values: dict[str, float | None]
    ci95: dict[str, float | None]
    undetermined: tuple[str, ...]
    taken_as_given: tuple[str, ...]
    reduced_chi2: float | None
    converged: bool
    band_hz: tuple[float, float]
    body_frequency_hz: float | None
    body_frequency_ci95_hz: float | None
    body_damping_ratio: float | None
    wheel_frequency_hz: float | None
    wheel_frequency_ci95_hz: float | None
    wheel_damping_ratio: float | None
    unsprung_mass_above_kg: float | None

    @classmethod
    def of(cls, car: QuarterCarFit) -> QuarterCarDoc:
        return cls(
            values=_numbers(car.values),
            ci95=_numbers(car.ci95),
            undetermined=tuple(car.undetermined),
            taken_as_given=tuple(car.taken_as_given),
            reduced_chi2=_number(car.reduced_chi2),
            converged=bool(car.converged),
            band_hz=_pair(car.band_hz),
            body_frequency_hz=_number(car.body_frequency_hz),
            body_frequency_ci95_hz=_number(car.body_frequency_ci95_hz),
            body_damping_ratio=_number(car.body_damping_ratio),
            wheel_frequency_hz=_number(car.wheel_frequency_hz),
            wheel_frequency_ci95_hz=_number(car.wheel_frequency_ci95_hz),
            wheel_damping_ratio=_number(car.wheel_damping_ratio),
            unsprung_mass_above_kg=_number(car.suspension.unsprung_mass_above_kg),
        )


@dataclass(frozen=True)
class FourPostDoc:
    """A four-post sweep: the tyre below the sensor, m_comp of the post, m_wheel, the three valid
    bands, the quarter car and the bins and amplitude the sweep gave."""

    label: str
    tyre_model: int
    tyre_source: str
    post_free_run: FreeRunDoc
    m_wheel_kg: float | None
    m_wheel_sigma_kg: float | None
    m_wheel_band_hz: tuple[float, float]
    m_wheel_given_kg: float
    accelerometer_delay_s: float | None
    valid_band_raw: BandDoc
    valid_band_hub_compensated: BandDoc
    valid_band_model_compensated: BandDoc
    quarter_car: QuarterCarDoc
    n_bins: int
    unreliable_bins: int
    unreliable_flank_hz: tuple[float, ...]
    unreliable_low_excitation_hz: tuple[float, ...]
    amplitude_m: float | None
    measured_amplitude_m: float | None
    findings: tuple[str, ...]

    @classmethod
    def of(cls, result: FourPostResult) -> FourPostDoc:
        m = result.wheel_mass
        flank_hz, other_hz = result.unreliable_bins_hz
        return cls(
            label=result.label,
            tyre_model=int(result.tyre_model),
            tyre_source=result.tyre_source,
            post_free_run=FreeRunDoc.of(result.post_free_run),
            m_wheel_kg=_number(m.mass_kg),
            m_wheel_sigma_kg=_number(m.sigma_kg),
            m_wheel_band_hz=_pair(m.band_hz),
            m_wheel_given_kg=float(result.wheel_mass_given_kg),
            accelerometer_delay_s=_number(m.accelerometer_delay_s),
            valid_band_raw=BandDoc.of(result.valid_band_raw),
            valid_band_hub_compensated=BandDoc.of(result.valid_band_hub_compensated),
            valid_band_model_compensated=BandDoc.of(result.valid_band_model_compensated),
            quarter_car=QuarterCarDoc.of(result.quarter_car),
            n_bins=int(result.frfs.wfs_per_z.freq_hz.size),
            unreliable_bins=int(result.unreliable_bins),
            unreliable_flank_hz=_floats(flank_hz),
            unreliable_low_excitation_hz=_floats(other_hz),
            amplitude_m=_number(result.amplitude_m),
            measured_amplitude_m=_number(result.measured_amplitude_m),
            findings=tuple(result.findings),
        )


@dataclass(frozen=True)
class ForceErrorsDoc:
    """One force's error against the contact force (N): rms in the error band and per octave."""

    rms_n: float | None
    octave_rms_n: tuple[float | None, ...]

    @classmethod
    def of(cls, errors: ForceErrors) -> ForceErrorsDoc:
        return cls(_number(errors.rms_n), tuple(_number(e) for e in errors.octave_rms_n))


@dataclass(frozen=True)
class ReplayErrorsDoc:
    """A road replay's forces against the contact force: the raw and the hub-acceleration
    compensated force always, the model-compensated one when the campaign gives a model (None)."""

    raw: ForceErrorsDoc
    hub_compensated: ForceErrorsDoc
    model_compensated: ForceErrorsDoc | None

    @classmethod
    def of(cls, errors: Mapping[str, ForceErrors]) -> ReplayErrorsDoc:
        model = errors.get("model_compensated")
        return cls(
            raw=ForceErrorsDoc.of(errors["raw"]),
            hub_compensated=ForceErrorsDoc.of(errors["hub_compensated"]),
            model_compensated=None if model is None else ForceErrorsDoc.of(model),
        )


@dataclass(frozen=True)
class RoadReplayDoc:
    """A road replay: its drive, the corrections used and each force's error against the contact
    force; the model compensation's basis and band, or why there is none."""

    run_id: str
    drive_source: str
    span_s: float
    sample_rate_hz: float
    m_comp_kg: float | None
    m_wheel_kg: float | None
    accelerometer_delay_s: float | None
    error_band_hz: tuple[float, float]
    octave_centres_hz: tuple[float, ...]
    contact_rms_n: float | None
    errors: ReplayErrorsDoc
    identification: str | None
    valid_band_hz: tuple[float, float] | None
    model_omitted: str | None

    @classmethod
    def of(cls, run_id: str, result: RoadReplayResult) -> RoadReplayDoc:
        return cls(
            run_id=run_id,
            drive_source=result.source,
            span_s=float(result.span_s),
            sample_rate_hz=float(result.sample_rate_hz),
            m_comp_kg=_number(result.plate_mass_kg),
            m_wheel_kg=_number(result.wheel_mass_kg),
            accelerometer_delay_s=_number(result.accelerometer_delay_s),
            error_band_hz=_pair(ERROR_BAND_HZ),
            octave_centres_hz=_floats(OCTAVE_CENTRES_HZ),
            contact_rms_n=_number(result.contact_rms_n),
            errors=ReplayErrorsDoc.of(result.errors),
            identification=result.identification or None,
            valid_band_hz=None if result.valid_band_hz is None else _pair(result.valid_band_hz),
            model_omitted=result.model_omitted or None,
        )


@dataclass(frozen=True)
class IterationDoc:
    """One iteration of a drive iteration: its run, the drive played and its errors."""

    run_id: str
    iteration: int
    drive_crc32: str
    rms_error_pct: float | None
    octave_error_pct: tuple[float | None, ...]
    in_band_pct: float | None
    damage_ratio: float | None
    target_rms: float | None
    error_rms: float | None
    stop_rules_met: bool

    @classmethod
    def of(cls, run_id: str, result: IterationResult) -> IterationDoc:
        return cls(
            run_id=run_id,
            iteration=int(result.iteration),
            drive_crc32=result.drive_crc32,
            rms_error_pct=_number(result.rms_error_pct),
            octave_error_pct=tuple(_number(e) for e in result.octave_error_pct),
            in_band_pct=None if result.in_band_pct is None else _number(result.in_band_pct),
            damage_ratio=_number(result.damage_ratio),
            target_rms=_number(result.target_rms),
            error_rms=_number(result.error_rms),
            stop_rules_met=bool(result.stop_rules_met),
        )


@dataclass(frozen=True)
class DriveIterationDoc:
    """A drive iteration's step: what it matched against which target, and its iterations in
    order; ``rms_error_pct`` again as one list over them (how the error fell)."""

    step_run_id: str
    response: str
    unit: str
    target: str
    error_band_hz: tuple[float, float]
    octave_centres_hz: tuple[float, ...]
    sn_exponent: float
    rms_error_pct: tuple[float | None, ...]
    iterations: tuple[IterationDoc, ...]

    @classmethod
    def all_of(cls, results: Mapping[str, IterationResult]) -> tuple[DriveIterationDoc, ...]:
        """One per step, from each drive's result by its run id."""
        return tuple(cls.of(step_run_id, runs) for step_run_id, runs in by_step(results).items())

    @classmethod
    def of(cls, step_run_id: str, runs: list[tuple[str, IterationResult]]) -> DriveIterationDoc:
        """The step ``step_run_id`` from its drives' (run id, result), in iteration order."""
        first = runs[0][1]
        iterations = tuple(IterationDoc.of(run_id, r) for run_id, r in runs)
        return cls(
            step_run_id=step_run_id,
            response=first.response,
            unit=first.unit,
            target=first.target_source,
            error_band_hz=_pair(first.band_hz),
            octave_centres_hz=_floats(OCTAVE_CENTRES_HZ),
            sn_exponent=float(first.sn_exponent),
            rms_error_pct=tuple(i.rms_error_pct for i in iterations),
            iterations=iterations,
        )


@dataclass(frozen=True)
class RunDoc:
    """A complete run: what was analysed, how far it got, where its results were stored, and its
    text report."""

    run_id: str
    kind: str
    analysis: str
    results_name: str | None
    status: str
    error: str | None
    omitted: tuple[str, ...]
    summary: tuple[str, ...]

    @classmethod
    def of(cls, run: RunAnalysis, results_name: str | None) -> RunDoc:
        return cls(
            run_id=run.run_id,
            kind=run.kind,
            analysis=str(run.name),
            results_name=results_name,
            status=str(run.status),
            error=run.error or None,
            omitted=tuple(run.omitted),
            summary=tuple(str(line) for line in run.lines),
        )


@dataclass(frozen=True)
class NotAnalysedDoc:
    """A run that did not complete, with its status."""

    run_id: str
    status: str

    @classmethod
    def of(cls, skipped: tuple[str, str]) -> NotAnalysedDoc:
        """From the analysis's (run id, status) of a run it skipped."""
        run_id, status = skipped
        return cls(run_id, status)


@dataclass(frozen=True)
class FlagDoc:
    """A flag of a run's analysis: its code and its text line."""

    run_id: str
    code: str
    flag: str

    @classmethod
    def of(cls, run_id: str, flag: Flag) -> FlagDoc:
        return cls(run_id, str(flag.code), flag.line)


@dataclass(frozen=True)
class AnalysisDocument:
    """The whole analysis of a campaign file: where it comes from, the masses and sensor used, each
    bench's results, every run, and every flag."""

    schema: str
    version: int
    file: str
    software_version: str
    sequence_name: str
    sequences: tuple[SequenceDoc, ...]
    config_source: str
    analysis_source: str
    metadata: dict[str, str]
    status: str
    given: GivenDoc
    sensor: SensorDoc
    hammer: HammerDoc | None
    shaker: tuple[ShakerPressureDoc, ...]
    four_post: FourPostDoc | None
    road_replays: tuple[RoadReplayDoc, ...]
    drive_iterations: tuple[DriveIterationDoc, ...]
    runs: tuple[RunDoc, ...]
    not_analysed: tuple[NotAnalysedDoc, ...]
    flags: tuple[FlagDoc, ...]

    @classmethod
    def of(
        cls, analysis: CampaignAnalysis, results_names: Mapping[str, str] | None = None
    ) -> AnalysisDocument:
        """``analysis`` as the document; ``results_names``: run id -> the name its results were
        stored under (from :func:`~bench.app.analyze.store_reanalysis`; none: not stored)."""
        k = analysis.knowledge
        names = results_names or {}
        return cls(
            schema=SCHEMA,
            version=VERSION,
            file=str(analysis.path),
            software_version=analysis.software_version,
            sequence_name=analysis.sequence_name,
            sequences=tuple(SequenceDoc.of(sequence) for sequence in analysis.sequences),
            config_source=analysis.config_source,
            analysis_source=analysis.source,
            metadata={name: analysis.metadata.get(name, "") for name in METADATA_FIELDS},
            status=str(analysis.status),
            given=GivenDoc.of(analysis),
            sensor=SensorDoc.of(analysis),
            hammer=None if k.hammer is None else HammerDoc.of(k.hammer),
            shaker=tuple(ShakerPressureDoc.of(p, r) for p, r in sorted(k.shaker.items())),
            four_post=None if k.four_post is None else FourPostDoc.of(k.four_post),
            road_replays=tuple(RoadReplayDoc.of(run_id, r) for run_id, r in k.road_replays.items()),
            drive_iterations=DriveIterationDoc.all_of(k.drive_iterations),
            runs=tuple(RunDoc.of(run, names.get(run.run_id)) for run in analysis.runs),
            not_analysed=tuple(NotAnalysedDoc.of(skipped) for skipped in analysis.skipped),
            flags=tuple(FlagDoc.of(run.run_id, flag) for run in analysis.runs for flag in run.flags),
        )

