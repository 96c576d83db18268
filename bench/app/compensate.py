"""``wfsbench compensate``: a measurement compensated with what a campaign identified.

The campaign file stores each run's analysis as a summary and a few scalars (docs/hdf5.md,
*Results*), not the fits' covariances nor the designed filters, so the campaign is analysed here
exactly as ``wfsbench analyze`` analyses it (nothing is written to it) and the compensation is
built from that analysis (:func:`compensation_basis`):

- the tyre: the shaker identification at the measurement's tyre pressure (within
  :data:`~bench.analysis.campaign.PRESSURE_MATCH_BAR`; no interpolation between pressures: the
  paper's 250 / 390 / 420 kN/m at 1.5 / 2.5 / 3.5 bar are far from a line, and the error of an
  interpolation is unknown); of its amplitudes the one nearest the measurement's tyre deflection
  (``sqrt 2`` times the rms of the dynamic Fz over the tyre's stiffness, an equivalent sine), the
  others kept for the amplitude dependence; the selected model's fit with its covariance;
- the wheel mass (weighed, as the identification takes it) and, when the campaign has a four-post
  run, its estimate's standard uncertainty and the accelerometer's lag it measured;
- the sensor (the hammer test's, else as configured), its damping ratio uncertain by half the
  difference of the hammer test's two estimates;
- the sensors' noise from the dwells' residuals; the filters' band, length and latency from the
  campaign's compensator; the valid band where the campaign verified it.

Everything a measurement needs that the campaign does not cover is refused, naming it
(:class:`CompensationRefusedError`).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Protocol

import numpy as np

from bench.analysis.campaign import PRESSURE_MATCH_BAR, CampaignKnowledge
from bench.analysis.measurement_compensation import (
    CompensationBasis,
    CompensationFilters,
    CompensationStream,
    design_filters,
)
from bench.analysis.records import HUB_ACCELERATION, WFS_FORCE
from bench.analysis.runs import ShakerAmplitudeResult
from bench.analysis.tyre_fit import PLATE_MASS_OFFSET
from bench.analysis.validation import AnalysisInputError
from bench.store.measurement import Measurement


class CompensationRefusedError(ValueError):
    """The campaign does not cover the measurement: the message names what is missing."""


class IdentifiedCampaign(Protocol):
    """What a compensation takes of a campaign: what its runs established (``knowledge``) and its
    ``path``, which messages name (a whole file analysed, :class:`~bench.analysis.campaign.
    CampaignAnalysis`, or the campaign a run's analysis is part of)."""

    @property
    def path(self) -> Path: ...

    @property
    def knowledge(self) -> CampaignKnowledge: ...


@dataclass(frozen=True)
class Compensation:
    """A measurement and the filters it is compensated with, ready to run block by block."""

    measurement: Measurement
    filters: CompensationFilters
    accelerometer_offset_m_s2: float

    def blocks(self):
        """The compensated force and its 95 % half-width, block by block (:class:`CompensatedBlock`)."""
        channels = self.measurement.channels
        stream = CompensationStream(self.filters)
        yield from stream.blocks(
            channels[WFS_FORCE], channels[HUB_ACCELERATION], self.accelerometer_offset_m_s2
        )


def _shaker_at(analysis: IdentifiedCampaign, pressure_bar: float | None):
    shaker = analysis.knowledge.shaker
    if not shaker:
        raise CompensationRefusedError(
            f"{analysis.path}: the campaign identified no tyre (no dwell grid with the wheel was"
            " analysed): there is nothing to compensate with"
        )
    known = ", ".join(f"{p:g}" for p in sorted(shaker))
    if pressure_bar is None:
        raise CompensationRefusedError(
            f"the measurement's tyre pressure is not known (give --pressure BAR): the campaign"
            f" identified the tyre at {known} bar"
        )
    nearest = min(shaker, key=lambda p: abs(p - pressure_bar))
    if abs(nearest - pressure_bar) > PRESSURE_MATCH_BAR:
        raise CompensationRefusedError(
            f"tyre pressure {pressure_bar:g} bar: the campaign identified the tyre at {known} bar only"
            f" (within {PRESSURE_MATCH_BAR:g} bar); the stiffness between pressures is not known well"
            " enough to interpolate: identify the tyre at the measurement's pressure"
        )
    return nearest, shaker[nearest]


def _noise(result: ShakerAmplitudeResult, channel: str) -> float:
    """The channel's white noise (rms per sample): the median residual of the dwells' fits."""
    residuals = [fit.channels[channel].residual_rms for fit in result.fits if channel in fit.channels]
    return float(np.median(residuals)) if residuals else 0.0


def _valid_band(
    analysis: IdentifiedCampaign, chosen: ShakerAmplitudeResult, pressure_bar: float
) -> tuple[float, float]:
    """Where the campaign verified the compensation: the shaker's compensated band (the tyre path,
    hub clamped), within the four-post's model-compensated band when the campaign has one (the hub
    acceleration's path too: only a moving hub tests it)."""
    bands = [chosen.valid_band_compensated]
    if analysis.knowledge.four_post is not None:
        bands.append(analysis.knowledge.four_post.valid_band_model_compensated)
    for band in bands:
        if not band.determined:
            raise CompensationRefusedError(
                f"the compensation of the tyre at {pressure_bar:g} bar, {chosen.label} has no valid band"
                " (the campaign's data did not verify it)"
            )
    return max(b.lowest_hz for b in bands), min(b.upper_hz for b in bands)


def compensation_basis(
    analysis: IdentifiedCampaign, measurement: Measurement, pressure_bar: float | None
) -> CompensationBasis:
    """What the campaign ``analysis`` gives the compensation of ``measurement`` at ``pressure_bar``
    (see the module docstring); :class:`CompensationRefusedError` naming what is missing."""
    identified_bar, shaker = _shaker_at(analysis, pressure_bar)
    if not shaker.amplitudes:
        raise CompensationRefusedError(
            f"the tyre at {identified_bar:g} bar has no fit at any amplitude (too few dwells)"
        )
    fz = measurement.channels[WFS_FORCE]
    stiffness = next(iter(shaker.amplitudes.values())).identification.best_fit.tyre.stiffness_n_per_m
    deflection_m = np.sqrt(2) * np.std(fz) / stiffness
    amplitude = min(shaker.amplitudes, key=lambda a: abs(a - deflection_m))
    chosen = shaker.amplitudes[amplitude]
    fit = chosen.identification.best_fit
    valid_band_hz = _valid_band(analysis, chosen, identified_bar)
    names = [name for name in fit.lsq.values if name != PLATE_MASS_OFFSET]
    index = [list(fit.lsq.values).index(name) for name in names]
    covariance = fit.lsq.covariance[np.ix_(index, index)]
    variances = {}
    four_post = analysis.knowledge.four_post
    delay_s = 0.0
    if four_post is not None:
        variances["wheel_mass_kg"] = four_post.wheel_mass.sigma_kg**2
        delay_s = four_post.wheel_mass.accelerometer_delay_s
    hammer = analysis.knowledge.hammer
    if hammer is not None:
        variances["sensor_damping_ratio"] = (
            (hammer.damping_ratio_half_power - hammer.damping_ratio_log_decrement) / 2
        ) ** 2
    full = np.zeros((len(names) + len(variances),) * 2)
    full[: len(names), : len(names)] = covariance
    full[len(names) :, len(names) :] = np.diag(list(variances.values()))
    comp = chosen.compensator
    return CompensationBasis(
        label=f"tyre at {identified_bar:g} bar, {chosen.label} (Model {int(fit.model)})",
        model=fit.model,
        tyre=fit.tyre,
        rubber=fit.rubber,
        sensor=shaker.sensor,
        parameters=(*names, *variances),
        covariance=full,
        alternatives=tuple(
            (
                r.label,
                r.identification.best_fit.model,
                r.identification.best_fit.tyre,
                r.identification.best_fit.rubber,
            )
            for a, r in shaker.amplitudes.items()
            if a != amplitude
        ),
        accelerometer_delay_s=delay_s,
        noise_wfs_n=_noise(chosen, WFS_FORCE),
        noise_accel_m_s2=_noise(chosen, HUB_ACCELERATION),
        band_hz=comp.band_hz,
        filter_s=comp.taps_wfs.size / comp.fs_hz,
        latency_s=comp.latency_samples / comp.fs_hz,
        valid_band_hz=valid_band_hz,
    )


def prepare_compensation(
    analysis: IdentifiedCampaign, measurement: Measurement, pressure_bar: float | None
) -> Compensation:
    """The basis from the campaign and the filters at the measurement's rate; refused (naming
    what) when the campaign does not cover the measurement. The hub acceleration's offset (its mean
    over the record: a hub does not accelerate on average) is removed before filtering."""
    basis = compensation_basis(analysis, measurement, pressure_bar)
    try:
        filters = design_filters(basis, measurement.sample_rate_hz)
    except AnalysisInputError as exc:
        raise CompensationRefusedError(f"{measurement.source}: {exc}") from None
    if measurement.n_samples < filters.n_taps:
        raise CompensationRefusedError(
            f"{measurement.source}: {measurement.n_samples} samples, fewer than the filters'"
            f" {filters.n_taps} taps: nothing could be compensated"
        )
    offset = float(np.mean(measurement.channels[HUB_ACCELERATION]))
    return Compensation(measurement, filters, offset)


def write_output(
    compensation: Compensation, out: Path, *, campaign: Path, campaign_analysis: str = ""
) -> list[str]:
    """Compensate the whole measurement block by block into the HDF5 file ``out``
    (:func:`bench.store.compensated.write_compensated`); the lines that say what was done.
    ``campaign_analysis``: where the campaign's analysis came from (its stored records, or a refit)."""
    from bench.app.version import software_version
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
        "valid_band_hz": np.array(basis.valid_band_hz),
        "design_band_hz": basis.band_hz,
        "accelerometer_delay_s": basis.accelerometer_delay_s,
        "accelerometer_offset_m_s2": compensation.accelerometer_offset_m_s2,
        "noise_wfs_n": basis.noise_wfs_n,
        "noise_accel_m_s2": basis.noise_accel_m_s2,
        "amplitude_alternatives": ", ".join(label for label, *_ in basis.alternatives),
    }
    arrays = {
        "filters/taps_wfs": filters.compensator.taps_wfs,
        "filters/taps_accel": filters.compensator.taps_accel,
        "parameters/names": np.array(basis.parameters, dtype=object),
        "parameters/values": np.array([basis.value(name) for name in basis.parameters]),
        "parameters/covariance": basis.covariance,
    }
    u95 = []

    def blocks():
        for block in compensation.blocks():
            u95.append(np.nanmedian(block.u95_n) if np.isfinite(block.u95_n).any() else np.nan)
            yield block

    write_compensated(
        out,
        n_samples=measurement.n_samples,
        sample_rate_hz=filters.fs_hz,
        start_s=measurement.start_s,
        blocks=blocks(),
        attributes=attributes,
        arrays=arrays,
    )
    lo, hi = basis.valid_band_hz
    return [
        f"campaign {campaign}: {basis.label}",
        f"measurement {measurement.source}: {measurement.n_samples} samples at {filters.fs_hz:g} Hz",
        f"filters {filters.n_taps} taps, latency {filters.latency_samples} samples"
        f" ({1e3 * filters.latency_samples / filters.fs_hz:g} ms), valid band {lo:.4g}-{hi:.4g} Hz",
        f"95 % band: median half-width {np.nanmedian(u95):.3g} N",
    ]
