"""What the compensation of a measurement (``wfsbench compensate``) rests on besides the tyre the
campaign identified, each said as an :class:`Assumption` (docs/compensate.md, *The measurement's
chain*):

- the tyre pressure: the campaign's identification at the measurement's pressure, or within
  :data:`~bench.analysis.campaign.PRESSURE_MATCH_BAR` of it (a gauge's resolution), said so; any
  other pressure is refused, between identified ones too (no interpolation);
- the hub accelerometer's lag: the measurement's as stated (:mod:`bench.store.measurement_chain`),
  the campaign's four-post lag only when stated so or for a run of the campaign file itself, else 0;
- the valid band: where the campaign verified the compensation, ended at the logger's stated
  bandwidth;
- each sensor's noise: the larger of the campaign's (the dwells' residuals) and the one the
  measurement shows above the filters' band (:mod:`bench.analysis.measurement_noise`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from bench.analysis.campaign import PRESSURE_MATCH_BAR, CampaignKnowledge
from bench.analysis.measurement_noise import (
    MIN_NOISE_BAND_HZ,
    NOISE_BAND_END_FRACTION,
    estimable,
    noise_band_hz,
    white_noise_rms,
)
from bench.analysis.records import HUB_ACCELERATION, WFS_FORCE
from bench.analysis.runs import ShakerAmplitudeResult, ShakerCampaignResult
from bench.store.measurement import Measurement
from bench.store.measurement_chain import CAMPAIGN_LAG

#: Pressures this close (bar) are one reading: float arithmetic, not a gauge.
_SAME_PRESSURE_BAR = 1e-9


class CompensationRefusedError(ValueError):
    """The campaign does not cover the measurement: the message names what is missing."""


class MeasurementChainError(ValueError):
    """What is stated of the measurement's chain contradicts the measurement itself (a logger's
    bandwidth above half its sample rate): an input that cannot be used."""


class IdentifiedCampaign(Protocol):
    """What a compensation takes of a campaign: what its runs established (``knowledge``) and its
    ``path``, which messages name (a whole file analysed, :class:`~bench.analysis.campaign.
    CampaignAnalysis`, or the campaign a run's analysis is part of)."""

    @property
    def path(self) -> Path: ...

    @property
    def knowledge(self) -> CampaignKnowledge: ...


@dataclass(frozen=True)
class Assumption:
    """One thing a compensation rests on that the measurement does not show by itself, as the
    output states it (text, JSON, the output file's attributes).

    ``key``: ``tyre_pressure``, ``hub_lag``, ``bandwidth``, ``noise_wfs``, ``noise_accel``,
    ``valid_band`` or ``identification`` (the identification used is flagged); ``source``:
    ``stated`` (the command line, the measurement's mapping or record), ``campaign`` (what the
    campaign identified), ``measured`` (estimated from the measurement) or ``assumed`` (nothing
    stated: a default taken); ``text``: the sentence printed; ``values``: its
    numbers by name, the unit in the name (None: not known), the same names in the JSON and as the
    output file's attributes."""

    key: str
    source: str
    text: str
    values: dict[str, float | list[float] | None]

    @property
    def line(self) -> str:
        return f"{self.source}: {self.text}"


def shaker_at(
    analysis: IdentifiedCampaign, pressure_bar: float | None
) -> tuple[float, ShakerCampaignResult, Assumption]:
    """The shaker identification at the measurement's tyre pressure and what it assumed of the
    pressure: the identified pressure itself, or one within :data:`PRESSURE_MATCH_BAR` (a gauge's
    resolution: two readings that far apart may be one pressure), said so; anything else is
    refused (between identified pressures too: no interpolation)."""
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
    if abs(nearest - pressure_bar) > PRESSURE_MATCH_BAR + _SAME_PRESSURE_BAR:
        raise CompensationRefusedError(_pressure_refusal(pressure_bar, sorted(shaker)))
    return nearest, shaker[nearest], _pressure_assumption(pressure_bar, nearest)


def _pressure_refusal(pressure_bar: float, identified_bar: list[float]) -> str:
    """Why a tyre pressure no identification matches is refused: between two identified ones (not
    interpolated), or beyond them (not extrapolated)."""
    below = [p for p in identified_bar if p < pressure_bar]
    above = [p for p in identified_bar if p > pressure_bar]
    within = f"within {PRESSURE_MATCH_BAR:g} bar, a gauge's resolution"
    if below and above:
        where = (
            f"lies between the campaign's identifications at {below[-1]:g} and {above[0]:g} bar"
            f" ({within}, of neither)"
        )
    else:
        where = f"the campaign identified the tyre at {', '.join(f'{p:g}' for p in identified_bar)} bar only"
        where += f" ({within})"
    return (
        f"tyre pressure {pressure_bar:g} bar: {where}; the stiffness between pressures is not known well"
        " enough to interpolate (its error would not be in the band): identify the tyre at the"
        " measurement's pressure"
    )


def _pressure_assumption(pressure_bar: float, identified_bar: float) -> Assumption:
    values = {"tyre_pressure_bar": pressure_bar, "identified_pressure_bar": identified_bar}
    if abs(pressure_bar - identified_bar) <= _SAME_PRESSURE_BAR:
        text = f"tyre pressure {pressure_bar:g} bar: the campaign identified the tyre at that pressure"
        return Assumption("tyre_pressure", "stated", text, values)
    difference_bar = abs(pressure_bar - identified_bar)
    text = (
        f"tyre pressure {pressure_bar:g} bar taken as the campaign's identification at"
        f" {identified_bar:g} bar: within {PRESSURE_MATCH_BAR:g} bar, a gauge's resolution (two readings"
        f" that far apart may be one pressure); the band does not hold the {difference_bar:.2g} bar between"
    )
    return Assumption("tyre_pressure", "assumed", text, values)


def _campaign_noise(result: ShakerAmplitudeResult, channel: str) -> float:
    """The channel's white noise (rms per sample) on the bench: the median residual of the dwells'
    fits (0 when the dwells carry no such channel: a clamped hub needs no accelerometer)."""
    residuals = [fit.channels[channel].residual_rms for fit in result.fits if channel in fit.channels]
    return float(np.median(residuals)) if residuals else 0.0


#: How the output names each channel's noise: text, unit, the key of its assumption and values.
_NOISE_NAMES = {
    WFS_FORCE: ("Fz", "N", "noise_wfs", "n"),
    HUB_ACCELERATION: ("hub acceleration", "m/s^2", "noise_accel", "m_s2"),
}


def sensor_noise(
    chosen: ShakerAmplitudeResult, measurement: Measurement, channel: str, design_band_hz: float
) -> tuple[float, Assumption]:
    """The channel's white noise the band carries: the larger of the campaign's (the bench's sensor)
    and what the measurement shows above the filters' band (its own chain: sensor, cable, logger),
    both estimates of one noise where the chain is the same; and what was assumed."""
    name, unit, key, suffix = _NOISE_NAMES[channel]
    campaign = _campaign_noise(chosen, channel)
    stated = measurement.chain.bandwidth_hz
    fs = measurement.sample_rate_hz
    band = noise_band_hz(design_band_hz, fs, None if stated is None else float(stated.value))
    measured = white_noise_rms(measurement.channels[channel], fs, band) if estimable(band) else None
    used = max(campaign, measured or 0.0)
    values = {
        f"{key}_{suffix}": used,
        f"{key}_campaign_{suffix}": campaign,
        f"{key}_measured_{suffix}": measured,
        "noise_band_hz": list(band) if measured is not None else None,
    }
    campaign_text = f"the campaign's {campaign:.3g} {unit} (its dwells' residuals)"
    if measured is None:
        end = (
            "its logger's bandwidth"
            if band[1] < NOISE_BAND_END_FRACTION * fs
            else f"{NOISE_BAND_END_FRACTION:g} of its rate"
        )
        text = (
            f"{name} noise {used:.3g} {unit} rms per sample: {campaign_text}; the measurement's own is not"
            f" estimated: it shows no {MIN_NOISE_BAND_HZ:g} Hz between the filters' stop band,"
            f" {band[0]:.4g} Hz, and {band[1]:.4g} Hz ({end})"
        )
        return used, Assumption(key, "campaign" if campaign > 0 else "assumed", text, values)
    shown = (
        f"{measured:.3g} {unit} the measurement shows at {band[0]:.4g}-{band[1]:.4g} Hz (above what the"
        " filters take of it)"
    )
    if measured >= campaign:
        text = f"{name} noise {used:.3g} {unit} rms per sample: the {shown}, above {campaign_text}"
        return used, Assumption(key, "measured", text, values)
    text = f"{name} noise {used:.3g} {unit} rms per sample: {campaign_text}, above the {shown}"
    return used, Assumption(key, "campaign", text, values)


def _run_of(measurement: Measurement, analysis: IdentifiedCampaign) -> bool:
    """Whether ``measurement`` is a run of the campaign file ``analysis`` analysed."""
    if measurement.campaign_file is None:
        return False
    try:
        return os.path.samefile(measurement.campaign_file, analysis.path)
    except OSError:  # a campaign that is no file on disk (a run's analysis of the campaign so far)
        return False


def _lag(analysis: IdentifiedCampaign, measurement: Measurement) -> tuple[float, str, str]:
    """The hub accelerometer's lag (s), where it comes from (``stated``, ``campaign``, ``assumed``)
    and why, as :func:`hub_lag` says it."""
    four_post = analysis.knowledge.four_post
    campaign_s = four_post.wheel_mass.accelerometer_delay_s if four_post is not None else None
    stated = measurement.chain.hub_lag_ms
    if stated is not None and stated.value == CAMPAIGN_LAG:
        if campaign_s is None:
            raise CompensationRefusedError(
                f"{stated.where} states the campaign's accelerometer, but the campaign has no four-post run:"
                " it measured no accelerometer's lag; state the measurement's in ms"
            )
        why = f"{stated.where} states the campaign's accelerometer, whose lag its four-post run measured"
        return campaign_s, "stated", why
    if stated is not None:
        return float(stated.value) / 1e3, "stated", f"as {stated.where} states"
    if campaign_s is not None and _run_of(measurement, analysis):
        why = "the measurement is a run of the campaign file itself, whose four-post run measured it"
        return campaign_s, "campaign", why
    measured = (
        f"the campaign's four-post run measured {1e3 * campaign_s:.3g} ms of its own accelerometer, not"
        " applied to another's"
        if campaign_s is not None
        else "the campaign measured no accelerometer's lag"
    )
    why = (
        f"the measurement states none, so an accelerometer without lag ({measured}); state it with"
        f" --hub-lag-ms MS, or --hub-lag-ms {CAMPAIGN_LAG} for the campaign's accelerometer"
    )
    return 0.0, "assumed", why


def hub_lag(
    analysis: IdentifiedCampaign, measurement: Measurement, latency_s: float
) -> tuple[float, Assumption]:
    """The hub accelerometer's lag (s) the filters undo, and what was assumed: the measurement's
    stated lag (or the campaign's, stated so with :data:`CAMPAIGN_LAG`); unstated, the campaign's
    for a run of the campaign file itself (its accelerometer is the one the four-post run measured),
    else 0 (an accelerometer without lag), said so: another accelerometer's lag is never applied.
    Refused when the filters' latency ``latency_s`` cannot undo it."""
    lag_s, source, why = _lag(analysis, measurement)
    if lag_s >= latency_s:
        raise CompensationRefusedError(
            f"hub accelerometer lag {1e3 * lag_s:g} ms ({why}): the filters' latency of"
            f" {1e3 * latency_s:g} ms cannot undo that much"
        )
    four_post = analysis.knowledge.four_post
    campaign_ms = None if four_post is None else 1e3 * four_post.wheel_mass.accelerometer_delay_s
    text = f"hub accelerometer lag {1e3 * lag_s:.3g} ms undone: {why}"
    values = {"hub_lag_ms": 1e3 * lag_s, "campaign_hub_lag_ms": campaign_ms}
    return lag_s, Assumption("hub_lag", source, text, values)


def _verified_band(
    analysis: IdentifiedCampaign, chosen: ShakerAmplitudeResult, pressure_bar: float
) -> tuple[tuple[float, float], str]:
    """Where the campaign verified the compensation, and how: the shaker's compensated band (the
    tyre path, hub clamped), within the four-post's model-compensated band when the campaign has one
    (the hub acceleration's path too: only a moving hub tests it)."""
    bands = [chosen.valid_band_compensated]
    how = "the shaker's compensated band (hub clamped)"
    if analysis.knowledge.four_post is not None:
        bands.append(analysis.knowledge.four_post.valid_band_model_compensated)
        how += " within the four-post sweep's model-compensated band (hub moving)"
    else:
        how += " only: the campaign has no four-post run, so the hub acceleration's path is not verified"
    for band in bands:
        if not band.determined:
            raise CompensationRefusedError(
                f"the compensation of the tyre at {pressure_bar:g} bar, {chosen.label} has no valid band"
                " (the campaign's data did not verify it)"
            )
    return (max(b.lowest_hz for b in bands), min(b.upper_hz for b in bands)), how


def valid_band(
    analysis: IdentifiedCampaign, chosen: ShakerAmplitudeResult, pressure_bar: float, measurement: Measurement
) -> tuple[tuple[float, float], Assumption, Assumption]:
    """The valid band: where the campaign verified the compensation (:func:`_verified_band`), ended
    at the logger's stated bandwidth (above it the logger did not pass the signals unchanged); and
    what was assumed of the bandwidth and the band. A bandwidth above half the rate contradicts the
    measurement (:class:`MeasurementChainError`); one at or below the band's start leaves nothing
    valid (refused)."""
    verified_hz, how = _verified_band(analysis, chosen, pressure_bar)
    lo, hi = verified_hz
    stated = measurement.chain.bandwidth_hz
    verified = {"valid_band_hz": [lo, hi], "verified_band_hz": [lo, hi]}
    if stated is None:
        text = (
            f"logger bandwidth not stated: taken to pass Fz and the hub acceleration unchanged up to the"
            f" valid band's {hi:.4g} Hz (state it with --bandwidth-hz HZ)"
        )
        band_text = f"valid band {lo:.4g}-{hi:.4g} Hz: {how}"
        return (
            verified_hz,
            Assumption("bandwidth", "assumed", text, {"bandwidth_hz": None}),
            Assumption("valid_band", "campaign", band_text, verified),
        )
    bandwidth = float(stated.value)
    nyquist = measurement.sample_rate_hz / 2
    if bandwidth > nyquist:
        raise MeasurementChainError(
            f"{stated.where} {bandwidth:g} Hz: above half the measurement's sample rate ({nyquist:g} Hz):"
            " no logger passes that"
        )
    if bandwidth <= lo:
        raise CompensationRefusedError(
            f"{stated.where} {bandwidth:g} Hz: the logger's bandwidth ends at or below the valid band's"
            f" start, {lo:.4g} Hz: nothing of the compensation would be valid"
        )
    band = (lo, min(hi, bandwidth))
    text = f"logger bandwidth {bandwidth:g} Hz ({stated.where})"
    if bandwidth < hi:
        text += f": the valid band ends there, not at the campaign's {hi:.4g} Hz"
        how += f", ended at the logger's bandwidth, {bandwidth:g} Hz"
    values = {"valid_band_hz": list(band), "verified_band_hz": [lo, hi]}
    return (
        band,
        Assumption("bandwidth", "stated", text, {"bandwidth_hz": bandwidth}),
        Assumption("valid_band", "campaign", f"valid band {band[0]:.4g}-{band[1]:.4g} Hz: {how}", values),
    )
