"""Whole recorded runs in, typed self-describing results out: the top-level analysis API.

- :func:`analyse_free_run`: m_comp of a bench's plate from its free run (no wheel).
- :func:`analyse_shaker_campaign`: the dwell grids of one tyre (one or more amplitudes) with the
  shaker's free run: m_comp, plate-mass corrected FRFs, Models 1-3 per amplitude with the model
  the data supports and what it cannot determine, the amplitude dependence of stiffness and
  damping, the model compensator of each amplitude and the valid bands raw and compensated.
- :func:`analyse_four_post`: a four-post sweep with the post's free run and the tyre's shaker
  identification: m_comp of the post, m_wheel and the accelerometer's lag from the run, the FRFs
  and the hub-acceleration relation, the valid bands raw / hub-acceleration / model compensated,
  the quarter car above the sensor and its body and wheel modes.
- :func:`analyse_hammer`: the sensor's eigenfrequency, damping and stiffness from a hammer blow.

The results are data: their text, JSON, figures and HTML are rendered by :mod:`bench.report`.
Every error names the record or the amplitude it comes from.

The model compensator is designed over ``DESIGN_BAND_MARGIN`` times the highest analysed frequency
(the FIR rolls off above its band, so the band must cover the data with some room).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import numpy as np

from bench.analysis.compensation import (
    ModelCompensator,
    WheelMass,
    advance_acceleration,
    design_model_compensator,
    estimate_wheel_mass,
    hub_acceleration_compensation,
)
from bench.analysis.dwell import DwellFit, dwell_frf, dwell_phasors
from bench.analysis.frf import Frf, ValidBand, phasor_ratio, valid_band
from bench.analysis.hammer import HammerResult, analyse_hammer_decay
from bench.analysis.plate_mass import (
    PlateMass,
    ShakerFrfs,
    base_acceleration_signal,
    contact_force_phasors,
    identify_plate_mass,
    shaker_frfs,
)
from bench.analysis.quarter_car_fit import FourPostFrfs, QuarterCarFit, fit_quarter_car, four_post_frfs
from bench.analysis.records import (
    AMPLITUDE_MISMATCH,
    DEFAULT_SETTLE_S,
    DISPLACEMENT,
    FREE_RUN_CHANNELS,
    HAMMER_FORCE,
    HUB_ACCELERATION,
    MIN_FIT_POINTS,
    PLATE_FORCE,
    SHAKER_CHANNELS,
    WFS_FORCE,
    WHEEL_CHANNELS,
    DwellRecord,
    HammerRecord,
    SweepRecord,
    amplitude_label,
    dwell_problems,
    fit_dwell_record,
    on_true_times,
    record_channels,
)
from bench.analysis.repeats import RepeatSpread, combine_repeats, spread_of_repeats
from bench.analysis.shaker_models import LINEAR, RubberTerms
from bench.analysis.tyre_fit import (
    AmplitudeDependence,
    RatioPeak,
    ShakerIdentification,
    TyreFit,
    identify_shaker,
    ratio_peak,
    tabulate_amplitude_dependence,
)
from bench.analysis.validation import AnalysisInputError
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor

#: Design band of the model compensator over the highest analysed frequency.
DESIGN_BAND_MARGIN = 1.15
#: Unreliable sweep bins in a row that do not end a valid band (one noisy bin is not its end; the
#: dwell grids' points are far apart and any unreliable dwell ends the band).
SWEEP_MAX_GAP_BINS = 1
#: The wheel mass is estimated from the sweep between 1 Hz (or the sweep's start) and this fraction
#: of its end: the band-pass's skirts then stay inside the swept band.
WHEEL_MASS_BAND_TOP_FRACTION = 5 / 6


@contextmanager
def _named(label: str) -> Iterator[None]:
    """Prefix any input error raised inside with ``label`` (which record or amplitude)."""
    try:
        yield
    except AnalysisInputError as err:
        raise AnalysisInputError(f"{label}: {err}") from err


def _positive(name: str, value: float) -> float:
    if not (np.isfinite(value) and value > 0):
        raise AnalysisInputError(f"{name} must be positive and finite, got {value}")
    return float(value)


def _unsettled(records: Sequence[DwellRecord], fits: Sequence[DwellFit]) -> tuple[str, ...]:
    return tuple(
        f"{r.label}: " + ("; ".join(f.notes) or "not settled")
        for r, f in zip(records, fits, strict=True)
        if not f.settled
    )


@dataclass(frozen=True)
class _Grid:
    """A grid's dwells fitted: ``records`` and ``fits`` (one per frequency, ascending: repeats
    combined, the first repeat's record standing for them), ``rejected`` (label and why) and
    ``repeats`` (how far each repeated point's repeats spread)."""

    records: list[DwellRecord]
    fits: list[DwellFit]
    rejected: tuple[str, ...]
    repeats: tuple[RepeatSpread, ...]


def _fit_grid(records: Sequence[DwellRecord], channels: tuple[str, ...], settle_s: float, what: str) -> _Grid:
    """Fit every dwell of a grid, sorted by frequency. Dwells with a problem
    (:func:`~bench.analysis.records.dwell_problems`: dead or frozen channel, the actuator not
    following, a mislabelled record) are left out and returned as ``rejected`` (label and why);
    dwells at the same frequency are repeats, combined (:mod:`bench.analysis.repeats`); the rest is
    analysed."""
    if not records:
        raise AnalysisInputError(f"{what}: no dwell records given")
    kept: dict[float, list[tuple[DwellRecord, DwellFit]]] = {}
    rejected = []
    signal = tuple(c for c in channels if c != HUB_ACCELERATION)  # the shaker clamps the hub
    for record in sorted(records, key=lambda r: r.freq_hz):
        fit = fit_dwell_record(record, channels, settle_s=settle_s)
        problems = dwell_problems(record, fit, signal)
        if problems:
            rejected.append(f"{record.label}: {'; '.join(problems)}")
        else:
            kept.setdefault(record.freq_hz, []).append((record, fit))
    if not kept:
        raise AnalysisInputError(f"{what}: every dwell was rejected ({'; '.join(rejected)})")
    spreads = []
    for same in kept.values():
        fits = [fit for _, fit in same]
        if len(fits) > 1:
            responses = [c for c in signal if c != DISPLACEMENT]
            spreads.append(spread_of_repeats(same[0][0].label, fits, DISPLACEMENT, responses))
    return _Grid(
        [same[0][0] for same in kept.values()],
        [
            same[0][1] if len(same) == 1 else combine_repeats([f for _, f in same], DISPLACEMENT)
            for same in kept.values()
        ],
        tuple(rejected),
        tuple(spreads),
    )


def _group_amplitudes(records: Sequence[DwellRecord]) -> dict[float, list[DwellRecord]]:
    """Dwells by their grid's amplitude (a dwell a bench limit lowered stays with its grid);
    amplitudes with the same label (4 significant digits: 2e-3 and 2.0000001e-3 m) are one group,
    keyed by the group's most common amplitude."""
    by_label: dict[str, list[DwellRecord]] = {}
    for r in records:
        _positive(f"{r.label}: amplitude", r.amplitude_m)
        by_label.setdefault(amplitude_label(r.grid_amplitude_m), []).append(r)
    groups = {}
    for members in by_label.values():
        amplitudes = [float(r.grid_amplitude_m) for r in members]
        groups[max(set(amplitudes), key=amplitudes.count)] = members
    return dict(sorted(groups.items()))


# ---------------------------------------------------------------------------------------- free run


@dataclass(frozen=True)
class FreeRunResult:
    """m_comp of a bench's plate from its free run: ``plate`` (mass, sigma, residual), the dwell
    ``fits`` (ascending frequency) and ``unsettled``: the dwells that did not settle, with why
    (their points are left out of m_comp); ``findings``: what the user must know about m_comp
    (:func:`plate_mass_findings`); ``repeats``: the dwells measured more than once, combined, with
    their spread."""

    plate: PlateMass
    fits: tuple[DwellFit, ...]
    unsettled: tuple[str, ...]
    rejected: tuple[str, ...] = ()
    findings: tuple[str, ...] = ()
    nominal_source: str = ""
    repeats: tuple[RepeatSpread, ...] = ()

    @property
    def nominal(self) -> bool:
        """Whether m_comp is a stated mass (``nominal_source`` says whose), not measured."""
        return bool(self.nominal_source)


def nominal_free_run(mass_kg: float, source: str) -> FreeRunResult:
    """m_comp taken as stated, not measured, where a campaign has no free run: ``mass_kg`` from
    ``source`` (how reports name it, e.g. ``the bench configuration's masses.plate_kg``), with no
    uncertainty of its own (none is known: the shaker analysis says what an error in it does)."""
    _positive("nominal plate mass", mass_kg)
    return FreeRunResult(PlateMass(float(mass_kg), 0.0, float("nan"), 0), (), (), nominal_source=source)


def plate_mass_findings(plate: PlateMass) -> tuple[str, ...]:
    """Findings on m_comp: a mass that is not positive and finite (a plate cannot weigh zero or
    less, so the plate force or the displacement has the wrong sign or unit in the record), and a
    rigid-mass fit outside the free run's noise: beyond any noise (:attr:`PlateMass.beyond_noise`:
    something besides the plate moved with it, such as a wheel left on the bench), or only outside it
    (:attr:`PlateMass.outside_noise`: a good plate does that once in a thousand free runs)."""
    findings = [reason] if (reason := plate_mass_distrust(plate)) else []
    if plate.outside_noise and not plate.beyond_noise:
        findings.append(
            f"m_comp misses the free run outside its noise (reduced chi^2 {plate.reduced_chi2:.3g},"
            f" residual {plate.residual_rms_n_per_m:.3g} N/m rms; a rigid plate does this in fewer than"
            " 1 of 1000 free runs): check the free run's record; m_comp keeps the interval its noise gives"
        )
    return tuple(findings)


def plate_mass_distrust(plate: PlateMass) -> str:
    """Why m_comp must not correct the contact force of the runs after it (empty: it may): a mass
    that is not physical, or a fit that no noise explains (:attr:`PlateMass.beyond_noise`)."""
    if not (np.isfinite(plate.mass_kg) and plate.mass_kg > 0):
        return (
            f"m_comp {plate.mass_kg:.4g} kg is not physical (a plate mass is positive):"
            f" check the sign and units of the plate force {PLATE_FORCE} and the displacement {DISPLACEMENT}"
        )
    if plate.beyond_noise:
        return (
            f"m_comp misses the free run beyond any noise (reduced chi^2 {plate.reduced_chi2:.3g},"
            f" residual {plate.residual_rms_n_per_m:.3g} N/m rms): the plate did not move as a rigid"
            " mass (was the specimen removed?); m_comp and every contact force corrected with it are"
            " not to be trusted"
        )
    return ""


def analyse_free_run(records: Sequence[DwellRecord], *, settle_s: float = DEFAULT_SETTLE_S) -> FreeRunResult:
    """m_comp from the free-run dwells (channels ``z_base_m``, ``f_plate_n``), flagged when it is
    not a positive mass or its fit misses the data (:func:`plate_mass_findings`)."""
    grid = _fit_grid(records, FREE_RUN_CHANNELS, settle_s, "free run")
    with _named("free run"):
        plate = identify_plate_mass(dwell_frf(grid.fits, PLATE_FORCE, DISPLACEMENT))
    return FreeRunResult(
        plate,
        tuple(grid.fits),
        _unsettled(grid.records, grid.fits),
        grid.rejected,
        plate_mass_findings(plate),
        repeats=grid.repeats,
    )


# ---------------------------------------------------------------------------------------- shaker


@dataclass(frozen=True)
class ShakerAmplitudeResult:
    """One amplitude's dwell grid of a shaker campaign.

    ``fits``: the dwells (ascending frequency); ``frfs``: F_wfs/Z, F_contact/Z (N/m) and
    F_wfs/F_contact, plate-mass corrected, with uncertainties; ``identification``: Models 1-3 and
    the one the data supports (lowest BIC); ``compensator``: the model-based inverse of the selected
    model; ``compensated_per_contact``: compensated force over the contact force at each dwell (the
    compensator's response applied to the dwell phasors); ``valid_band_raw`` (F_wfs/F_contact) and
    ``valid_band_compensated``, both uncertainty-aware; ``unsettled``: dwells that did not settle
    (unreliable points, left out of the fits), with why; ``hub_acceleration_recorded``: false when
    the dwells carry no hub acceleration: the clamped hub is then taken as not moving (the
    compensated ratio without its ``G_A a_hub`` term), which nothing checks; ``repeats``: the
    dwells measured more than once, combined (one point each), with their spread;
    ``band_conditions``: what the model-compensated band rests on that the campaign did not measure,
    each with the error a stated deviation would cause (:func:`nominal_plate_condition`), and
    ``plate_mass_tolerance_kg``: how far a nominal m_comp may be off with the band still holding
    (None: m_comp was measured).
    """

    amplitude_m: float
    fits: tuple[DwellFit, ...]
    frfs: ShakerFrfs
    identification: ShakerIdentification
    compensator: ModelCompensator
    compensated_per_contact: Frf
    valid_band_raw: ValidBand
    valid_band_compensated: ValidBand
    unsettled: tuple[str, ...]
    rejected: tuple[str, ...] = ()
    model_peak: RatioPeak | None = None
    hub_acceleration_recorded: bool = True
    repeats: tuple[RepeatSpread, ...] = ()
    band_conditions: tuple[str, ...] = ()
    plate_mass_tolerance_kg: float | None = None

    @property
    def label(self) -> str:
        return amplitude_label(self.amplitude_m)

    @property
    def largest_measured_ratio(self) -> tuple[float, float]:
        """The largest reliable measured ``|F_wfs/F_contact|`` as (frequency in Hz, magnitude)."""
        raw = self.frfs.wfs_per_contact
        top = int(np.argmax(np.where(raw.reliable, np.abs(raw.value), -np.inf)))
        return float(raw.freq_hz[top]), float(np.abs(raw.value[top]))


@dataclass(frozen=True)
class ShakerRatiosResult:
    """One amplitude's dwell grid with too few reliable points for a tyre fit: the measured ratios
    (``frfs``: F_wfs/Z, F_contact/Z, F_wfs/F_contact with their uncertainties), the raw valid band,
    the dwells left out, and ``why`` there is no fit (no model, compensator or compensated band)."""

    amplitude_m: float
    fits: tuple[DwellFit, ...]
    frfs: ShakerFrfs
    valid_band_raw: ValidBand
    why: str
    unsettled: tuple[str, ...]
    rejected: tuple[str, ...] = ()
    hub_acceleration_recorded: bool = True
    repeats: tuple[RepeatSpread, ...] = ()

    @property
    def label(self) -> str:
        return amplitude_label(self.amplitude_m)


@dataclass(frozen=True)
class ShakerCampaignResult:
    """The shaker campaign of one tyre: ``free_run`` (m_comp), ``amplitudes`` (ascending amplitude
    in m -> :class:`ShakerAmplitudeResult`, the amplitudes with a tyre fit), ``ratios_only`` (those
    with too few reliable dwells for a fit: :class:`ShakerRatiosResult`), ``amplitude_dependence``
    (Model 2 per fitted amplitude with the rubber terms any amplitude needed; ``None`` with fewer
    than two), and the given
    ``wheel_mass_kg`` (weighed) and ``sensor`` (hammer test, or as stated), with where the sensor
    comes from (``sensor_source``, as reports say it: ``from the hammer test``)."""

    wheel_mass_kg: float
    sensor: WfsSensor
    free_run: FreeRunResult
    amplitudes: dict[float, ShakerAmplitudeResult]
    amplitude_dependence: AmplitudeDependence | None
    sensor_source: str = "given"
    ratios_only: dict[float, ShakerRatiosResult] = field(default_factory=dict)

    def nearest(self, amplitude_m: float) -> ShakerAmplitudeResult:
        """The fitted amplitude's result closest to ``amplitude_m`` (AnalysisInputError when no
        amplitude had enough dwells for a fit)."""
        if not self.amplitudes:
            raise AnalysisInputError(
                "no amplitude of this tyre's shaker campaign has a tyre fit (too few dwells)"
            )
        return self.amplitudes[min(self.amplitudes, key=lambda a: abs(a - amplitude_m))]


def _ratio_band(ratio: Frf, max_gap_points: int = 0) -> ValidBand:
    """The uncertainty-aware valid band of a force ratio (measured over true contact force)."""
    return valid_band(
        ratio.freq_hz, ratio.value, ratio.reliable, sigma=ratio.sigma, max_gap_points=max_gap_points
    )


def _sweep_ratio(frfs: FourPostFrfs, response: str, name: str) -> Frf:
    """``response / F_contact`` of the sweep as ``name`` (see :attr:`FourPostFrfs.per_contact`:
    estimated from the whole record, so the sweep's flanks count with their full excitation)."""
    return replace(frfs.per_contact[response], output=name)


def _design_band(highest_hz: float, given_hz: float | None) -> float:
    return DESIGN_BAND_MARGIN * highest_hz if given_hz is None else given_hz


def _compensated_ratio(
    fits: Sequence[DwellFit], plate: PlateMass, comp: ModelCompensator, *, hub_recorded: bool
) -> Frf:
    """(G_F F_wfs + G_A a_hub) / F_contact per dwell from the phasors themselves (as the raw ratio
    of :func:`shaker_frfs`: no division by the displacement, whose error would enter numerator and
    denominator alike), with propagated uncertainty. Without a hub accelerometer
    (``hub_recorded`` false) the clamped hub is taken as not moving: ``a_hub = 0``."""
    f = np.sort([d.freq_hz for d in fits])
    g_f, g_a = comp.response(f)
    wfs, s_w = dwell_phasors(fits, WFS_FORCE)
    acc, s_a = dwell_phasors(fits, HUB_ACCELERATION) if hub_recorded else (np.zeros(f.size), np.zeros(f.size))
    contact, s_c = contact_force_phasors(fits, plate, shaker_force=PLATE_FORCE, displacement=DISPLACEMENT)
    num_sigma = np.hypot(np.abs(g_f) * s_w, np.abs(g_a) * s_a)
    ratio, sigma = phasor_ratio(g_f * wfs + g_a * acc, num_sigma, contact, s_c)
    reliable = np.array([d.settled for d in sorted(fits, key=lambda d: d.freq_hz)])
    return Frf(f, ratio, sigma, reliable, "f_compensated", "f_contact")


def _unreliable_plate_finding(ident: ShakerIdentification) -> str:
    """The finding of a shaker fit on an m_comp its free run does not describe: its error ``dm``
    enters every ``F_contact/Z`` as ``w^2 dm``, which a tread mass fits as well, so the tyre fit
    cannot see it (its chi^2 stays within the noise)."""
    return (
        f"Model {int(ident.best)} rests on an m_comp its free run does not describe (see the free run):"
        " its error enters the contact force as a mass and passes into the tread mass; the parameters,"
        " the ratio peak and the valid bands are not to be trusted"
    )


def _contact_per_dwell(
    fits: Sequence[DwellFit], plate: PlateMass
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each dwell's frequency (ascending), displacement phasor and contact-force phasor with
    ``plate``'s m_comp: what an error in m_comp is measured against."""
    z, _ = dwell_phasors(fits, DISPLACEMENT)
    contact, _ = contact_force_phasors(fits, plate, shaker_force=PLATE_FORCE, displacement=DISPLACEMENT)
    return np.sort([d.freq_hz for d in fits]), z, contact


def _nominal_plate_finding(fits: Sequence[DwellFit], plate: PlateMass) -> str:
    """What an error in a nominal m_comp does: each kilogram moves every dwell's contact force by
    ``w^2 |Z|`` newtons (``F_contact = F_shaker + m_comp w^2 Z``) and, since ``w^2 dm`` is the form
    of a tread mass's inertia, the tread mass by as much the other way; neither is in the fit's
    intervals (the mass has no uncertainty of its own)."""
    f, z, contact = _contact_per_dwell(fits, plate)
    per_kg_n = (2 * np.pi * f) ** 2 * np.abs(z)
    relative = per_kg_n / np.abs(contact)
    worst = int(np.argmax(relative))
    return (
        f"m_comp {plate.mass_kg:g} kg is nominal, not measured (no free run): each kg it is off moves"
        f" the contact force by {per_kg_n[-1]:.3g} N at {f[-1]:g} Hz ({100 * relative[-1]:.2g} % of it;"
        f" at most {100 * relative[worst]:.2g} % at {f[worst]:g} Hz) and the tread mass by 1 kg the"
        " other way; neither is in the intervals (a free run measures m_comp)"
    )


def _analyse_amplitude(
    amplitude_m: float,
    records: Sequence[DwellRecord],
    *,
    plate: PlateMass,
    wheel_mass_kg: float,
    sensor: WfsSensor,
    settle_s: float,
    band_hz: float | None,
) -> ShakerAmplitudeResult | ShakerRatiosResult:
    """One amplitude's grid analysed; with fewer than ``MIN_FIT_POINTS`` reliable dwells its
    measured ratios only."""
    label = amplitude_label(amplitude_m)
    hub_recorded = all(HUB_ACCELERATION in r.channels for r in records)
    channels = WHEEL_CHANNELS if hub_recorded else SHAKER_CHANNELS
    grid = _fit_grid(records, channels, settle_s, label)
    ordered, fits, rejected = grid.records, grid.fits, grid.rejected
    rates = {r.sample_rate_hz for r in ordered}
    if len(rates) != 1:
        raise AnalysisInputError(f"{label}: dwells at different sample rates {sorted(rates)}")
    with _named(label):
        frfs = shaker_frfs(fits, plate, wfs=WFS_FORCE, shaker_force=PLATE_FORCE, displacement=DISPLACEMENT)
        usable = int(np.sum(frfs.wfs_per_z.reliable & frfs.contact_per_z.reliable))
        if usable < MIN_FIT_POINTS:
            why = (
                f"{usable} reliable dwell{'s' if usable != 1 else ''}, a tyre fit needs at least"
                f" {MIN_FIT_POINTS} (Model 2 has three parameters and the fit a residual to be judged by)"
            )
            return ShakerRatiosResult(
                amplitude_m,
                tuple(fits),
                frfs,
                _ratio_band(frfs.wfs_per_contact),
                why,
                _unsettled(ordered, fits),
                rejected,
                hub_recorded,
                grid.repeats,
            )
        ident = identify_shaker(
            frfs.wfs_per_z, frfs.contact_per_z, wheel_mass_kg=wheel_mass_kg, sensor=sensor, errors=frfs.errors
        )
        if plate.beyond_noise:
            ident = replace(ident, findings=(*ident.findings, _unreliable_plate_finding(ident)))
        if plate.n_points == 0:
            ident = replace(ident, findings=(*ident.findings, _nominal_plate_finding(fits, plate)))
        best = ident.best_fit
        comp = design_model_compensator(
            best.model,
            best.tyre,
            sensor,
            best.rubber,
            fs_hz=rates.pop(),
            band_hz=_design_band(fits[-1].freq_hz, band_hz),
        )
        compensated = _compensated_ratio(fits, plate, comp, hub_recorded=hub_recorded)
        peak = ratio_peak(best, sensor, (fits[0].freq_hz, fits[-1].freq_hz))
        band_raw, band_comp = _ratio_band(frfs.wfs_per_contact), _ratio_band(compensated)
        tolerance_kg, conditions = None, ()
        if plate.n_points == 0:
            tolerance_kg, condition = nominal_plate_condition(fits, plate, compensated, band_comp)
            conditions = (condition,)
    return ShakerAmplitudeResult(
        amplitude_m,
        tuple(fits),
        frfs,
        ident,
        comp,
        compensated,
        band_raw,
        band_comp,
        _unsettled(ordered, fits),
        rejected,
        peak,
        hub_recorded,
        grid.repeats,
        conditions,
        tolerance_kg,
    )


#: The deviation of a nominal m_comp whose error a band's condition states (kg): a plate weighed on
#: a scale, or taken from a drawing, is known to about this.
STATED_PLATE_DEVIATION_KG = 0.5


def nominal_plate_condition(
    fits: Sequence[DwellFit], plate: PlateMass, compensated: Frf, band: ValidBand
) -> tuple[float, str]:
    """How far a nominal m_comp may be off with the model-compensated ``band`` still holding (kg),
    and the condition in words with the error :data:`STATED_PLATE_DEVIATION_KG` would cause.

    An error ``dm`` makes the true contact force ``C + dm w^2 Z`` where the ratio was measured
    against ``C``, and the tyre fit absorbs it into the tread mass, so the compensated ratio measured
    on the bench does not show it: against the true contact force it is ``H C / (C + dm w^2 Z)``.
    The tolerance is the smallest ``|dm|`` (either sign, on a grid 1 % apart) at which that leaves
    the band's tolerances at one of its points; the error at the stated deviation is the largest
    ``| |C / (C + dm w^2 Z)| - 1 |`` over the dwells."""
    f, z, contact = _contact_per_dwell(fits, plate)
    per_kg = (2 * np.pi * f) ** 2 * z / contact  # the true contact's change per kg, relative

    def true_ratio(dm_kg: np.ndarray) -> np.ndarray:  # (masses, dwells): the factor on H
        return 1 / (1 + dm_kg[:, None] * per_kg[None, :])

    stated = np.abs(np.abs(true_ratio(np.array([STATED_PLATE_DEVIATION_KG, -STATED_PLATE_DEVIATION_KG]))) - 1)
    worst = np.unravel_index(int(np.argmax(stated)), stated.shape)[1]
    at_deviation = f"{STATED_PLATE_DEVIATION_KG:g} kg off: {100 * np.max(stated):.3g} % at {f[worst]:.4g} Hz"
    if not band.determined:
        return 0.0, f"rests on the nominal m_comp {plate.mass_kg:g} kg (no free run; {at_deviation})"
    inside = (f >= band.lowest_hz) & (f <= band.upper_hz)
    steps_kg = np.geomspace(1e-4, 100.0, 1400)  # 1 % apart
    tolerance_kg = float(steps_kg[-1])
    for sign in (1.0, -1.0):
        ratio = compensated.value[inside][None, :] * true_ratio(sign * steps_kg)[:, inside]
        outside = (np.abs(np.abs(ratio) - 1) > band.amplitude_tolerance) | (
            np.abs(np.angle(ratio, deg=True)) > band.phase_tolerance_deg
        )
        broken = np.flatnonzero(outside.any(axis=1))
        if broken.size:
            tolerance_kg = min(tolerance_kg, float(steps_kg[max(broken[0] - 1, 0)]))
    return tolerance_kg, (
        f"holds only if the nominal m_comp {plate.mass_kg:g} kg (no free run) is right to"
        f" {1000 * tolerance_kg:.3g} g ({at_deviation})"
    )


def analyse_shaker_campaign(
    records: Sequence[DwellRecord],
    free_run: Sequence[DwellRecord] | FreeRunResult,
    *,
    wheel_mass_kg: float,
    sensor: WfsSensor,
    settle_s: float = DEFAULT_SETTLE_S,
    compensation_band_hz: float | None = None,
    sensor_source: str = "given",
) -> ShakerCampaignResult:
    """Analyse the shaker campaign of one tyre (at one pressure).

    ``records``: every dwell with the wheel (channels ``z_base_m``, ``f_plate_n``, ``fz_wfs_n``, and
    ``a_hub_m_s2`` when a hub accelerometer was recorded: the clamped hub needs none), grouped by
    their commanded ``amplitude_m``; ``free_run``: the dwells without a wheel (``z_base_m``,
    ``f_plate_n``), or m_comp as stated (:func:`nominal_free_run`), whose effect each amplitude's
    findings state. ``wheel_mass_kg``: the weighed mass below the sensor;
    ``sensor``: from the hammer test (or as the lab states it; ``sensor_source`` says which, as
    reports word it). ``compensation_band_hz``: the compensator's design band (default
    ``DESIGN_BAND_MARGIN`` times the highest dwell frequency of each amplitude).
    """
    _positive("wheel mass", wheel_mass_kg)
    if not records:
        raise AnalysisInputError("shaker campaign: no dwell records given")
    free = free_run if isinstance(free_run, FreeRunResult) else analyse_free_run(free_run, settle_s=settle_s)
    groups = _group_amplitudes(records)
    results = {
        a: _analyse_amplitude(
            a,
            groups[a],
            plate=free.plate,
            wheel_mass_kg=wheel_mass_kg,
            sensor=sensor,
            settle_s=settle_s,
            band_hz=compensation_band_hz,
        )
        for a in sorted(groups)
    }
    ratios = {a: r for a, r in results.items() if isinstance(r, ShakerRatiosResult)}
    results = {a: r for a, r in results.items() if isinstance(r, ShakerAmplitudeResult)}
    dependence = None
    if len(results) > 1:
        idents = [r.identification for r in results.values()]
        # every identification fitted Model 2 to its amplitude with each combination of rubber terms
        variant = (
            TyreModel.WHEEL_TREAD,
            any(i.frequency_dependent_stiffness for i in idents),
            any(i.hysteretic_damping for i in idents),
        )
        with _named("amplitude dependence"):
            dependence = tabulate_amplitude_dependence(
                {a: r.identification.tried[variant] for a, r in results.items()}
            )
    return ShakerCampaignResult(
        float(wheel_mass_kg), sensor, free, results, dependence, sensor_source, ratios
    )


# ---------------------------------------------------------------------------------------- four-post


@dataclass(frozen=True)
class FourPostResult:
    """A four-post sweep analysed.

    ``post_free_run``: m_comp of the post; ``wheel_mass``: m_wheel, its sigma and the accelerometer's
    lag estimated from this run, against ``wheel_mass_given_kg`` (weighed); ``tyre_model``,
    ``tyre``, ``rubber``, ``tyre_source``: the tyre below the sensor and where it comes from;
    ``frfs``: F_wfs/Z, F_contact/Z (post force, plate-mass corrected), a_hub/Z and the sweep
    details; ``apparent_mass_above``: the hub-acceleration relation F_wfs/a_hub (kg);
    ``wfs_per_contact`` (F_WFS/F_post), ``hub_compensated_per_contact`` and
    ``model_compensated_per_contact``: measured over true contact force, with their valid bands
    ``valid_band_raw``, ``valid_band_hub_compensated``, ``valid_band_model_compensated``
    (uncertainty-aware); ``compensator``: the model compensator applied; ``quarter_car``: the car
    above the sensor with its modes, what it does not determine and what it took as given;
    ``unreliable_bins``: bins of the swept band not reliable in all three FRFs;
    ``amplitude_m`` (declared) and ``measured_amplitude_m``: the displacement amplitude the record
    shows (:func:`sweep_amplitude_m`); ``findings``: what the user must know (a measured amplitude far from
    the declared one).
    """

    label: str
    post_free_run: FreeRunResult
    wheel_mass: WheelMass
    wheel_mass_given_kg: float
    tyre_model: TyreModel
    tyre: Tyre
    rubber: RubberTerms
    tyre_source: str
    frfs: FourPostFrfs
    apparent_mass_above: Frf
    wfs_per_contact: Frf
    hub_compensated_per_contact: Frf
    model_compensated_per_contact: Frf
    valid_band_raw: ValidBand
    valid_band_hub_compensated: ValidBand
    valid_band_model_compensated: ValidBand
    compensator: ModelCompensator
    quarter_car: QuarterCarFit
    unreliable_bins: int
    amplitude_m: float = float("nan")
    measured_amplitude_m: float = float("nan")
    findings: tuple[str, ...] = ()

    @property
    def unreliable_bins_hz(self) -> tuple[np.ndarray, np.ndarray]:
        """The bins not reliable in all three FRFs over Z (Hz), split into those on the sweep's
        flanks (biased over Z, usable in the force ratios) and those with low excitation or
        coherence."""
        f = self.frfs.wfs_per_z.freq_hz
        sweeps = self.frfs.sweeps
        frfs = (self.frfs.wfs_per_z, self.frfs.contact_per_z, self.frfs.accel_per_z)
        bad = ~np.logical_and.reduce([frf.reliable for frf in frfs])
        flank = bad & (sweeps["f_wfs"].flank | sweeps["f_plate"].flank | sweeps["a_hub"].flank)
        return f[flank], f[bad & ~flank]


def _tyre_below(
    tyre: ShakerCampaignResult | TyreFit | Tyre, tyre_model: TyreModel | None, amplitude_m: float
) -> tuple[TyreModel, Tyre, RubberTerms, str, ModelCompensator | None]:
    """The tyre below the sensor as (model, tyre, rubber, source, shaker compensator or None)."""
    if isinstance(tyre, Tyre):
        if tyre_model is None:
            raise AnalysisInputError("a given Tyre needs tyre_model (which of Models 1-3 it describes)")
        return TyreModel(tyre_model), tyre, LINEAR, "given parameters (linear)", None
    if tyre_model is not None:
        raise AnalysisInputError("tyre_model is only for a given Tyre: an identification has its own model")
    if isinstance(tyre, TyreFit):
        return tyre.model, tyre.tyre, tyre.rubber, "a given shaker identification", None
    if not isinstance(tyre, ShakerCampaignResult):
        raise AnalysisInputError(
            f"tyre must be a shaker campaign result, a TyreFit or a Tyre, got {type(tyre)}"
        )
    shaker = tyre.nearest(amplitude_m)
    fit = shaker.identification.best_fit
    return fit.model, fit.tyre, fit.rubber, f"the shaker identification at {shaker.label}", shaker.compensator


def sweep_amplitude_m(displacement_m: np.ndarray) -> float:
    """The displacement amplitude a sweep record shows: the median of its envelope (the magnitude
    of the analytic signal of the displacement less its median) over the record's middle half,
    clear of the tapers and of the transform's edge effects."""
    from scipy.signal import hilbert
    z = np.asarray(displacement_m, dtype=float)
    envelope = np.abs(hilbert(z - np.median(z)))
    quarter = z.size // 4
    return float(np.median(envelope[quarter : z.size - quarter]))


def _amplitude_findings(sweep: SweepRecord, measured_m: float) -> tuple[str, ...]:
    """A measured amplitude more than ``AMPLITUDE_MISMATCH`` from the declared one: the actuator did
    not follow, or the record's amplitude is mislabelled (the tyre's amplitude is chosen by it)."""
    if abs(measured_m / sweep.amplitude_m - 1) <= AMPLITUDE_MISMATCH:
        return ()
    return (
        f"{sweep.label}: measured displacement amplitude {1e3 * measured_m:.3g} mm (median over the"
        f" sweep's middle half) against the declared {1e3 * sweep.amplitude_m:g} mm: the actuator did"
        " not follow, or the amplitude is mislabelled (the shaker amplitude whose tyre is used is"
        " chosen by it)",
    )


def _checked_sweep(sweep: SweepRecord) -> tuple[dict[str, np.ndarray], tuple[tuple[int, int], ...]]:
    """The sweep's channels on their true sample times, after checking that it covers the band it
    claims (errors name it), and the stretches where frames were lost (first, end sample), which
    the channels only bridge (:func:`~bench.analysis.records.on_true_times`)."""
    rec, gaps = on_true_times(
        record_channels(sweep, WHEEL_CHANNELS, min_samples=64), sweep.sample_offsets, sweep.sample_rate_hz
    )
    fs = float(sweep.sample_rate_hz)
    with _named(sweep.label):
        if not 0 < sweep.start_hz < sweep.end_hz < fs / 2:
            raise AnalysisInputError(f"sweep band must satisfy 0 < start < end < {fs / 2:g} Hz")
        _positive("amplitude", sweep.amplitude_m)
        _positive("sweep duration", sweep.sweep_s)
        if sweep.duration_s < sweep.sweep_s - 1 / fs:
            raise AnalysisInputError(
                f"the record is {sweep.duration_s:.4g} s long but the sweep takes {sweep.sweep_s:g} s:"
                f" it covers {100 * sweep.duration_s / sweep.sweep_s:.0f} % of the sweep, not the"
                f" {sweep.start_hz:g}-{sweep.end_hz:g} Hz it claims"
            )
    return rec, gaps


def _lost_frames_findings(sweep: SweepRecord, gaps: tuple[tuple[int, int], ...]) -> tuple[str, ...]:
    """What the sweep lost on the WFS link, and where the gate closed the record around it: the
    bins swept there are left out of the FRFs."""
    if not gaps or sweep.sample_offsets is None:
        return ()
    fs = float(sweep.sample_rate_hz)
    lost = int(sweep.sample_offsets[-1]) + 1 - len(sweep.sample_offsets)
    where = ", ".join(f"{start / fs:.2f}-{end / fs:.2f} s" for start, end in gaps[:5])
    more = f" and {len(gaps) - 5} more" if len(gaps) > 5 else ""
    return (
        f"{sweep.label}: {lost} frames lost on the WFS link; the record is gated at {where}{more}:"
        " the bins swept there and the gate's main lobe around them are left out of every FRF and band",
    )


def _bridged(n: int, gaps: tuple[tuple[int, int], ...], widen: int) -> np.ndarray:
    """The samples of a record of ``n`` within ``widen`` samples of a lost stretch."""
    near = np.zeros(n, bool)
    for start, end in gaps:
        near[max(start - widen, 0) : min(end + widen, n)] = True
    return near


def _contact_force(
    rec: dict[str, np.ndarray], fs_hz: float, plate: PlateMass
) -> tuple[np.ndarray, np.ndarray]:
    """The post's acceleration ``z''`` and the contact force ``F_plate - m_comp z''`` (NaN where the
    differentiator lacks history or future)."""
    a_contact = base_acceleration_signal(rec[DISPLACEMENT], fs_hz)
    return a_contact, rec[PLATE_FORCE] - plate.mass_kg * a_contact


@dataclass(frozen=True)
class ForceDifferenceTrace:
    """The paper's Fig. 8 in time: over ``t_s`` (s from the record's start) the force the WFS does
    not see, ``F_contact - F_WFS`` (``difference_n``), and what the hub-acceleration compensation
    adds, ``m_wheel a_hub`` (``inertial_n``, a_hub advanced by the accelerometer's lag), each less
    its mean over the window (static load and tare are not dynamics), while the sweep passes
    ``freq_hz``."""

    t_s: np.ndarray
    difference_n: np.ndarray
    inertial_n: np.ndarray
    freq_hz: float


def force_difference_trace(
    sweep: SweepRecord, result: FourPostResult, *, around_hz: float = 8.0, cycles: int = 8
) -> ForceDifferenceTrace:
    """``cycles`` periods of the sweep from where it first reaches ``around_hz``, with the post's
    m_comp, m_wheel and the accelerometer's lag that ``result`` identified from the same sweep.
    The periods are found from the displacement whatever the sweep's law: its rises through half
    the amplitude above its median after a fall below half the amplitude under it (noise at rest
    and in the tapers crosses neither)."""
    rec, _ = _checked_sweep(sweep)
    fs = float(sweep.sample_rate_hz)
    _, f_contact = _contact_force(rec, fs, result.post_free_run.plate)
    z = rec[DISPLACEMENT] - np.median(rec[DISPLACEMENT])
    level = np.where(z > sweep.amplitude_m / 2, 1, np.where(z < -sweep.amplitude_m / 2, -1, 0))
    beyond = np.flatnonzero(level)
    ups = beyond[1:][(level[beyond[:-1]] < 0) & (level[beyond[1:]] > 0)]
    if len(ups) < cycles + 2:
        raise AnalysisInputError(f"{sweep.label}: too few cycles in the record for a trace")
    local_hz = fs / np.diff(ups)
    at = np.flatnonzero(local_hz >= around_hz)
    first = int(at[0]) if at.size else len(ups) - cycles - 1
    first = min(first, len(ups) - cycles - 1)
    span = slice(int(ups[first]), int(ups[first + cycles]))
    mass = result.wheel_mass
    inertial = mass.mass_kg * advance_acceleration(rec[HUB_ACCELERATION], fs, mass.accelerometer_delay_s)
    difference = (f_contact - rec[WFS_FORCE])[span]
    inertial = inertial[span]
    return ForceDifferenceTrace(
        t_s=np.arange(span.start, span.stop) / fs,
        difference_n=difference - difference.mean(),
        inertial_n=inertial - inertial.mean(),
        freq_hz=float(np.median(local_hz[first : first + cycles])),
    )


def _compensate_sweep(
    sweep: SweepRecord,
    rec: dict[str, np.ndarray],
    plate: PlateMass,
    comp: ModelCompensator,
    gaps: tuple[tuple[int, int], ...] = (),
) -> tuple[WheelMass, dict[str, np.ndarray], slice]:
    """m_wheel and the accelerometer's lag from the run (contact force ``F_plate - m_comp z''``, its
    samples near a lost stretch left out), the hub-acceleration and model-compensated forces, and
    the span of the record where the differentiator and the compensator are defined (their windows
    inside the record)."""
    fs = float(sweep.sample_rate_hz)
    a_contact, f_contact = _contact_force(rec, fs, plate)
    edge = int(np.argmax(np.isfinite(a_contact)))  # the differentiator's half-length
    inner = np.isfinite(a_contact) & ~_bridged(a_contact.size, gaps, edge)
    mass = estimate_wheel_mass(
        f_contact[inner],
        rec[WFS_FORCE][inner],
        rec[HUB_ACCELERATION][inner],
        fs,
        a_contact=a_contact[inner],
        band_hz=(max(1.0, sweep.start_hz), WHEEL_MASS_BAND_TOP_FRACTION * sweep.end_hz),
    )
    accel = advance_acceleration(rec[HUB_ACCELERATION], fs, mass.accelerometer_delay_s)
    compensated = {
        "hub_compensated": hub_acceleration_compensation(rec[WFS_FORCE], accel, mass.mass_kg),
        "model_compensated": comp.apply(rec[WFS_FORCE], accel),
    }
    idx = np.flatnonzero(inner & np.isfinite(compensated["model_compensated"]))
    return mass, compensated, slice(int(idx[0]), int(idx[-1]) + 1)


def analyse_four_post(
    sweep: SweepRecord,
    free_run: Sequence[DwellRecord],
    *,
    tyre: ShakerCampaignResult | TyreFit | Tyre,
    wheel_mass_kg: float,
    sensor: WfsSensor,
    tyre_model: TyreModel | None = None,
    settle_s: float = DEFAULT_SETTLE_S,
    compensation_band_hz: float | None = None,
    sensor_source: str = "given",
) -> FourPostResult:
    """Analyse a four-post sweep (channels ``z_base_m``, ``f_plate_n`` of the post's load cell,
    ``fz_wfs_n``, ``a_hub_m_s2``) with the post's free-run dwells.

    ``tyre``: the shaker campaign of the same tyre at the same pressure (its amplitude closest to
    the sweep's is used, with its compensator), one identification, or given parameters (then
    ``tyre_model`` says which model). ``wheel_mass_kg``: weighed, must be the mass the tyre
    describes. The compensator is the shaker campaign's (redesigned with its band if the sample
    rates differ), else designed over ``compensation_band_hz`` (default ``DESIGN_BAND_MARGIN``
    times the sweep's end). ``sensor_source``: where ``sensor`` comes from, as the quarter car's
    ``taken_as_given`` words it (``from the hammer test``).
    """
    label = sweep.label
    _positive("wheel mass", wheel_mass_kg)
    model, tyre_obj, rubber, source, shaker_comp = _tyre_below(tyre, tyre_model, sweep.amplitude_m)
    if not np.isclose(tyre_obj.wheel_mass_kg, wheel_mass_kg, rtol=1e-9, atol=0.0):
        raise AnalysisInputError(
            f"wheel mass {wheel_mass_kg:g} kg differs from the {tyre_obj.wheel_mass_kg:g} kg"
            " the tyre describes"
        )
    rec, gaps = _checked_sweep(sweep)
    fs = float(sweep.sample_rate_hz)
    measured_amplitude_m = sweep_amplitude_m(rec[DISPLACEMENT])
    post = analyse_free_run(free_run, settle_s=settle_s)
    with _named(label):
        if shaker_comp is not None and shaker_comp.fs_hz == fs:
            comp = shaker_comp
        else:
            band = (
                shaker_comp.band_hz
                if shaker_comp is not None
                else _design_band(sweep.end_hz, compensation_band_hz)
            )
            comp = design_model_compensator(model, tyre_obj, sensor, rubber, fs_hz=fs, band_hz=band)
        mass, compensated, keep = _compensate_sweep(sweep, rec, post.plate, comp, gaps)
        frfs = four_post_frfs(
            {name: x[keep] for name, x in rec.items()},
            fs,
            post.plate,
            band_hz=(sweep.start_hz, sweep.end_hz),
            displacement=DISPLACEMENT,
            post_force=PLATE_FORCE,
            wfs=WFS_FORCE,
            hub_acceleration=HUB_ACCELERATION,
            extra_responses={name: x[keep] for name, x in compensated.items()},
            gaps_s=tuple(((start - keep.start) / fs, (end - keep.start) / fs) for start, end in gaps),
        )
        ratios = {
            name: _sweep_ratio(frfs, response, name)
            for name, response in (
                ("raw", "f_wfs"),
                ("hub_compensated", "hub_compensated"),
                ("model_compensated", "model_compensated"),
            )
        }
        bands = {name: _ratio_band(ratio, SWEEP_MAX_GAP_BINS) for name, ratio in ratios.items()}
        car = fit_quarter_car(
            frfs,
            model=model,
            tyre=tyre_obj,
            sensor=sensor,
            amplitude_m=measured_amplitude_m,
            rubber=rubber,
            sensor_source=sensor_source,
        )
    all_reliable = frfs.wfs_per_z.reliable & frfs.contact_per_z.reliable & frfs.accel_per_z.reliable
    return FourPostResult(
        label=f"{label}, {sweep.duration_s:.1f} s at {fs:g} Hz",
        post_free_run=post,
        wheel_mass=mass,
        wheel_mass_given_kg=float(wheel_mass_kg),
        tyre_model=model,
        tyre=tyre_obj,
        rubber=rubber,
        tyre_source=source,
        frfs=frfs,
        apparent_mass_above=frfs.apparent_mass_above(),
        wfs_per_contact=ratios["raw"],
        hub_compensated_per_contact=ratios["hub_compensated"],
        model_compensated_per_contact=ratios["model_compensated"],
        valid_band_raw=bands["raw"],
        valid_band_hub_compensated=bands["hub_compensated"],
        valid_band_model_compensated=bands["model_compensated"],
        compensator=comp,
        quarter_car=car,
        unreliable_bins=int(np.sum(~all_reliable)),
        amplitude_m=float(sweep.amplitude_m),
        measured_amplitude_m=measured_amplitude_m,
        findings=(*_amplitude_findings(sweep, measured_amplitude_m), *_lost_frames_findings(sweep, gaps)),
    )


# ---------------------------------------------------------------------------------------- hammer


def analyse_hammer(record: HammerRecord, *, sensor_mass_kg: float) -> HammerResult:
    """The bare sensor's eigenfrequency, damping ratios (two methods) and stiffness from a hammer
    blow (channel ``fz_wfs_n``, and ``f_hammer_n`` when recorded, which marks the release)."""
    names = (WFS_FORCE, HAMMER_FORCE) if HAMMER_FORCE in record.channels else (WFS_FORCE,)
    sig = record_channels(record, names, min_samples=64)
    with _named(record.label):
        return analyse_hammer_decay(
            sig[WFS_FORCE], record.sample_rate_hz, sensor_mass_kg, hammer_n=sig.get(HAMMER_FORCE)
        )
