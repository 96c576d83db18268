"""``wfsbench compensate``: a measurement compensated with what a campaign identified.

The campaign file stores each run's analysis as a summary and a few scalars (docs/hdf5.md,
*Results*), not the fits' covariances nor the designed filters, so the campaign is analysed here
exactly as ``wfsbench analyze`` analyses it (nothing is written to it) and the compensation is
built from that analysis (:func:`compensation_basis`):

- the tyre: the shaker identification at the measurement's tyre pressure (within
  :data:`~bench.analysis.campaign.PRESSURE_MATCH_BAR`, a gauge's resolution, and said so; no
  interpolation between pressures: the paper's 250 / 390 / 420 kN/m at 1.5 / 2.5 / 3.5 bar are far
  from a line, and the error of an interpolation is unknown); of its amplitudes the one nearest the
  measurement's tyre deflection (``sqrt 2`` times the rms of the dynamic Fz over the tyre's
  stiffness, an equivalent sine), the others kept for the amplitude dependence; the selected
  model's fit with its covariance;
- the wheel mass (weighed, as the identification takes it) and, when the campaign has a four-post
  run, its estimate's standard uncertainty;
- the sensor (the hammer test's, else as configured), its damping ratio uncertain by half the
  difference of the hammer test's two estimates;
- the filters' band, length and latency from the campaign's compensator; the valid band where the
  campaign verified it.

The measurement's own chain (its hub accelerometer's lag, its logger's bandwidth, its sensors'
noise) and its tyre pressure are what :mod:`bench.app.compensation_assumptions` makes of them, each
an :class:`Assumption` the output states. Everything a measurement needs that the campaign does not
cover is refused, naming it (:class:`CompensationRefusedError`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from bench.analysis.blockwise import Moments, moments
from bench.analysis.measurement_compensation import (
    CompensationBasis,
    CompensationFilters,
    CompensationStream,
    TyreAlternative,
    design_filters,
)
from bench.analysis.records import HUB_ACCELERATION, WFS_FORCE
from bench.analysis.runs import ShakerAmplitudeResult
from bench.analysis.tyre_fit import PLATE_MASS_OFFSET
from bench.analysis.validation import AnalysisInputError
from bench.app.compensation_assumptions import (
    Assumption,
    CompensationRefusedError,
    IdentifiedCampaign,
    hub_lag,
    sensor_noise,
    shaker_at,
    valid_band,
)
from bench.store.compensated import OutputExistsError
from bench.store.measurement import Measurement
from bench.store.measurement_chain import MeasurementChain, Stated, merged

#: Schema and version of ``wfsbench compensate --json`` (docs/compensate.md).
JSON_SCHEMA = "wfs-bench-compensate"
JSON_VERSION = 1


@dataclass(frozen=True)
class Compensation:
    """A measurement and the filters it is compensated with, ready to run block by block, with what
    the compensation assumed (:class:`Assumption`, in the order the output states them)."""

    measurement: Measurement
    filters: CompensationFilters
    accelerometer_offset_m_s2: float
    assumptions: tuple[Assumption, ...] = ()

    def blocks(self):
        """The compensated force and its 95 % half-width, block by block (:class:`CompensatedBlock`)."""
        channels = self.measurement.channels
        stream = CompensationStream(self.filters)
        yield from stream.blocks(
            channels[WFS_FORCE], channels[HUB_ACCELERATION], self.accelerometer_offset_m_s2
        )


def _parameters(
    analysis: IdentifiedCampaign, chosen: ShakerAmplitudeResult
) -> tuple[tuple[str, ...], np.ndarray]:
    """The uncertain parameters and their covariance: the tyre fit's (the m_comp nuisance left
    out), the wheel mass's from a four-post run, the sensor's damping ratio from a hammer test."""
    fit = chosen.identification.best_fit
    names = [name for name in fit.lsq.values if name != PLATE_MASS_OFFSET]
    index = [list(fit.lsq.values).index(name) for name in names]
    covariance = fit.lsq.covariance[np.ix_(index, index)]
    variances = {}
    four_post = analysis.knowledge.four_post
    if four_post is not None:
        variances["wheel_mass_kg"] = four_post.wheel_mass.sigma_kg**2
    hammer = analysis.knowledge.hammer
    if hammer is not None:
        variances["sensor_damping_ratio"] = (
            (hammer.damping_ratio_half_power - hammer.damping_ratio_log_decrement) / 2
        ) ** 2
    full = np.zeros((len(names) + len(variances),) * 2)
    full[: len(names), : len(names)] = covariance
    full[len(names) :, len(names) :] = np.diag(list(variances.values()))
    return (*names, *variances), full


def _tyre_alternatives(
    amplitudes: Mapping[float, ShakerAmplitudeResult], chosen_m: float
) -> tuple[TyreAlternative, ...]:
    """The identifications whose spread is the band's model-form part: each other amplitude's (the
    tyre's amplitude dependence), and, where the chosen fit has rubber terms (a stiffness rise, a
    hysteretic loss), the same model fitted to the same data without them (a road tyre that does not
    follow the rate and amplitude dependence the bench measured: a linear tyre's road on class C at
    60 km/h lay outside the band without it)."""
    alternatives = []
    for amplitude_m, result in amplitudes.items():
        fit = result.identification.best_fit
        if amplitude_m != chosen_m:
            alternatives.append(TyreAlternative(result.label, fit.model, fit.tyre, fit.rubber))
    chosen = amplitudes[chosen_m]
    ident = chosen.identification
    linear = ident.tried.get((ident.best, False, False))
    if (ident.frequency_dependent_stiffness or ident.hysteretic_damping) and linear is not None:
        label = f"{chosen.label} fitted without rubber terms"
        alternatives.append(TyreAlternative(label, linear.model, linear.tyre, linear.rubber, linear_fit=True))
    return tuple(alternatives)


def compensation_basis(
    analysis: IdentifiedCampaign, measurement: Measurement, pressure_bar: float | None
) -> tuple[CompensationBasis, tuple[Assumption, ...]]:
    """What the campaign ``analysis`` gives the compensation of ``measurement`` at ``pressure_bar``
    (see the module docstring), and what it assumed; :class:`CompensationRefusedError` naming what
    is missing, :class:`MeasurementChainError` naming what contradicts the measurement."""
    identified_bar, shaker, pressure = shaker_at(analysis, pressure_bar)
    if not shaker.amplitudes:
        raise CompensationRefusedError(
            f"the tyre at {identified_bar:g} bar has no fit at any amplitude (too few dwells)"
        )
    stiffness = next(iter(shaker.amplitudes.values())).identification.best_fit.tyre.stiffness_n_per_m
    deflection_m = np.sqrt(2) * moments(measurement.channels[WFS_FORCE]).std / stiffness
    amplitude = min(shaker.amplitudes, key=lambda a: abs(a - deflection_m))
    chosen = shaker.amplitudes[amplitude]
    fit = chosen.identification.best_fit
    comp = chosen.compensator
    latency_s = comp.latency_samples / comp.fs_hz
    valid_band_hz, bandwidth, band = valid_band(analysis, chosen, identified_bar, measurement)
    delay_s, lag = hub_lag(analysis, measurement, latency_s)
    noise_wfs_n, noise_wfs = sensor_noise(chosen, measurement, WFS_FORCE, comp.band_hz)
    noise_accel_m_s2, noise_accel = sensor_noise(chosen, measurement, HUB_ACCELERATION, comp.band_hz)
    parameters, covariance = _parameters(analysis, chosen)
    basis = CompensationBasis(
        label=f"tyre at {identified_bar:g} bar, {chosen.label} (Model {int(fit.model)})",
        model=fit.model,
        tyre=fit.tyre,
        rubber=fit.rubber,
        sensor=shaker.sensor,
        parameters=parameters,
        covariance=covariance,
        alternatives=_tyre_alternatives(shaker.amplitudes, amplitude),
        accelerometer_delay_s=delay_s,
        noise_wfs_n=noise_wfs_n,
        noise_accel_m_s2=noise_accel_m_s2,
        band_hz=comp.band_hz,
        filter_s=comp.taps_wfs.size / comp.fs_hz,
        latency_s=latency_s,
        valid_band_hz=valid_band_hz,
    )
    flagged = _flagged_identification(chosen, identified_bar)
    return basis, (pressure, lag, bandwidth, noise_wfs, noise_accel, band, *flagged)


def _flagged_identification(chosen: ShakerAmplitudeResult, pressure_bar: float) -> tuple[Assumption, ...]:
    """What the campaign's analysis flagged about the identification the compensation rests on
    (its findings: a fit outside its noise, parameters not determined), said with the band, whose
    parameter part holds the fit's noise alone: a model error the flag names is not in it."""
    findings = chosen.identification.findings
    if not findings:
        return ()
    text = (
        f"the tyre at {pressure_bar:g} bar, {chosen.label} is flagged: {'; '.join(findings)}; the band's"
        " part for its parameters holds their noise alone, not what the flag names"
    )
    return (Assumption("identification", "campaign", text, {}),)


def with_stated_chain(
    measurement: Measurement, hub_lag_ms: float | str | None, bandwidth_hz: float | None
) -> Measurement:
    """The measurement with the chain the command line states (``--hub-lag-ms``, ``--bandwidth-hz``;
    None: not stated) beside the one its mapping states: both may state a value only when they
    agree (ValueError naming both)."""
    given = MeasurementChain(
        hub_lag_ms=None if hub_lag_ms is None else Stated(hub_lag_ms, "--hub-lag-ms"),
        bandwidth_hz=None if bandwidth_hz is None else Stated(bandwidth_hz, "--bandwidth-hz"),
    )
    return replace(measurement, chain=merged(measurement.chain, given))


def prepare_compensation(
    analysis: IdentifiedCampaign, measurement: Measurement, pressure_bar: float | None
) -> Compensation:
    """The basis from the campaign and the filters at the measurement's rate; refused (naming
    what) when the campaign does not cover the measurement. The hub acceleration's offset (its mean
    over the record: a hub does not accelerate on average) is removed before filtering."""
    basis, assumptions = compensation_basis(analysis, measurement, pressure_bar)
    try:
        filters = design_filters(basis, measurement.sample_rate_hz)
    except AnalysisInputError as exc:
        raise CompensationRefusedError(f"{measurement.source}: {exc}") from None
    if measurement.n_samples < filters.n_taps:
        raise CompensationRefusedError(
            f"{measurement.source}: {measurement.n_samples} samples, fewer than the filters'"
            f" {filters.n_taps} taps: nothing could be compensated"
        )
    offset = moments(measurement.channels[HUB_ACCELERATION]).mean
    return Compensation(measurement, filters, offset, assumptions)


def _assumption_attributes(assumptions: tuple[Assumption, ...]) -> dict[str, Any]:
    """The assumptions as the output file's root attributes: each value by its name (NaN where not
    known), each source as ``<key>_source``, and every line as printed in ``assumptions``."""
    attributes: dict[str, Any] = {}
    for assumption in assumptions:
        attributes[f"{assumption.key}_source"] = assumption.source
        for name, value in assumption.values.items():
            if isinstance(value, list):
                attributes[name] = np.array(value, dtype=float)
            elif name == "noise_band_hz":
                attributes[name] = np.full(2, math.nan)
            else:
                attributes[name] = math.nan if value is None else float(value)
    attributes["assumptions"] = "\n".join(a.line for a in assumptions)
    return attributes


@dataclass(frozen=True)
class CompensationOutput:
    """What ``wfsbench compensate`` did: the ``compensation`` written to ``out`` with the campaign
    file ``campaign`` (its analysis from ``campaign_analysis``), the band's median half-width
    ``median_u95_n`` and largest ``max_u95_n``, the compensated force's ``force`` moments (mean,
    spread, peaks), and its MDF 4 copy ``out_mdf4``; as lines of text (:meth:`lines`) or JSON
    (:meth:`to_json`)."""

    compensation: Compensation
    campaign: Path
    campaign_analysis: str
    out: Path
    median_u95_n: float
    force: Moments = field(default_factory=Moments)
    max_u95_n: float = math.nan
    out_mdf4: Path | None = None

    def lines(self) -> list[str]:
        filters, basis = self.compensation.filters, self.compensation.filters.basis
        measurement = self.compensation.measurement
        lo, hi = basis.valid_band_hz
        return [
            f"campaign {self.campaign}: {basis.label}",
            f"measurement {measurement.source}: {measurement.n_samples} samples at {filters.fs_hz:g} Hz",
            *(assumption.line for assumption in self.compensation.assumptions),
            f"filters {filters.n_taps} taps, latency {filters.latency_samples} samples"
            f" ({1e3 * filters.latency_samples / filters.fs_hz:g} ms), valid band {lo:.4g}-{hi:.4g} Hz",
            f"95 % band: median half-width {self.median_u95_n:.3g} N",
        ]

    def to_json(self, filters_path: Path | None) -> dict[str, Any]:
        """The versioned JSON of the command (docs/compensate.md, *JSON*)."""
        filters, basis = self.compensation.filters, self.compensation.filters.basis
        measurement = self.compensation.measurement
        return {
            "schema": JSON_SCHEMA,
            "version": JSON_VERSION,
            "campaign": str(self.campaign),
            "campaign_analysis": self.campaign_analysis,
            "measurement": measurement.source,
            "n_samples": measurement.n_samples,
            "sample_rate_hz": filters.fs_hz,
            "identification": basis.label,
            "n_taps": filters.n_taps,
            "latency_samples": filters.latency_samples,
            "valid_band_hz": list(basis.valid_band_hz),
            "median_u95_n": _finite_or_none(self.median_u95_n),
            "assumptions": {
                a.key: {"source": a.source, "text": a.text, **a.values} for a in self.compensation.assumptions
            },
            "out": str(self.out),
            "filters": None if filters_path is None else str(filters_path),
        }


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def write_output(
    compensation: Compensation,
    out: Path,
    *,
    campaign: Path,
    campaign_analysis: str = "",
    mdf4: Path | None = None,
    replace: bool = False,
) -> CompensationOutput:
    """Compensate the whole measurement block by block into the HDF5 file ``out``
    (:func:`bench.store.compensated.write_compensated`) and, given ``mdf4``, the same series into
    that MDF 4 file (:mod:`bench.export.compensated_mdf4`) in the same pass; what was done
    (:class:`CompensationOutput`). ``campaign_analysis``: where the campaign's analysis came from
    (its stored records, or a refit); ``replace``: older outputs at those paths are replaced (a job's
    own outputs of an input that changed), else an existing file is refused."""
    from bench.app.version import software_version
    from bench.export.compensated_mdf4 import CompensatedMdf4
    from bench.store.compensated import write_compensated

    filters, basis = compensation.filters, compensation.filters.basis
    measurement = compensation.measurement
    attributes = {
        "software_version": software_version(),
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "campaign": str(campaign),
        "campaign_analysis": campaign_analysis,
        "measurement": measurement.source,
        "identification": basis.label,
        "sample_rate_hz": filters.fs_hz,
        "n_taps": filters.n_taps,
        "latency_samples": filters.latency_samples,
        "design_band_hz": basis.band_hz,
        "accelerometer_delay_s": basis.accelerometer_delay_s,
        "accelerometer_offset_m_s2": compensation.accelerometer_offset_m_s2,
        "amplitude_alternatives": ", ".join(a.label for a in basis.alternatives if not a.linear_fit),
        "linear_fit_alternative": next((a.label for a in basis.alternatives if a.linear_fit), ""),
        **_assumption_attributes(compensation.assumptions),
    }
    arrays = {
        "filters/taps_wfs": filters.compensator.taps_wfs,
        "filters/taps_accel": filters.compensator.taps_accel,
        "parameters/names": np.array(basis.parameters, dtype=object),
        "parameters/values": np.array([basis.value(name) for name in basis.parameters]),
        "parameters/covariance": basis.covariance,
    }
    if mdf4 is not None and mdf4.exists() and not replace:
        raise OutputExistsError(f"{mdf4}: exists; the output is never replaced (choose another --out)")
    copy = (
        None
        if mdf4 is None
        else CompensatedMdf4(
            mdf4,
            sample_rate_hz=filters.fs_hz,
            start_s=measurement.start_s,
            comment=f"wfs-bench {software_version()}: {measurement.source} compensated with {campaign}"
            f" ({basis.label})",
        )
    )
    u95, force, band = [], Moments(), Moments()

    def blocks():
        for block in compensation.blocks():
            u95.append(np.nanmedian(block.u95_n) if np.isfinite(block.u95_n).any() else np.nan)
            force.add(block.force_n)
            band.add(block.u95_n)
            if copy is not None:
                copy.add(block.start, block.force_n, block.u95_n)
            yield block

    try:
        write_compensated(
            out,
            n_samples=measurement.n_samples,
            sample_rate_hz=filters.fs_hz,
            start_s=measurement.start_s,
            blocks=blocks(),
            attributes=attributes,
            arrays=arrays,
            replace=replace,
        )
    except BaseException:
        if copy is not None:
            copy.discard()
        raise
    if copy is not None:
        try:
            copy.save(replace=replace)
        except BaseException:
            out.unlink(missing_ok=True)  # the outputs come as a pair, or not at all
            raise
    return CompensationOutput(
        compensation, campaign, campaign_analysis, out, float(np.nanmedian(u95)), force, band.maximum, mdf4
    )
