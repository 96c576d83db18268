"""Drive iteration (time waveform replication): the numerics that make a rig's response match a
target, independent of any device (docs/analysis.md, *Drive iteration*).

1. **Identification**: the rig is driven with a low-level broadband drive (:func:`broadband_drive`:
   pink, a density falling as 1/f, or shaped like the target's own spectrum), and its frequency
   response from drive (mm) to the matched response is estimated by Welch's H1,
   ``H = G_xy / G_xx``, with the coherence ``gamma^2`` (:func:`estimate_frf`).
2. **The inverse** (:func:`regularised_inverse`): ``H^-1 ~ gamma^2 conj(H) / (gamma^2 |H|^2 +
   lambda max|H|^2)`` over the iteration band, zero outside it: Tikhonov regularisation with the
   stated ``lambda`` relative to the FRF's peak power, weighted by the coherence so that a frequency
   where the drive does not explain the response is corrected less (at coherence 1 it is the plain
   Tikhonov inverse; at coherence 0 nothing is driven).
3. **Drives**: the first is the inverse applied to the target (:func:`inverse_drive`); each next one
   is the present one corrected by ``gain`` times the inverse applied to the error
   (:func:`corrected_drive`), with ``0 < gain < 1``: where the rig's true response ``H_t`` differs
   from the estimate (a non-linear rig, identified at a lower level than the road), the error
   shrinks by ``|1 - gain H_t / H|`` per iteration, which a gain below 1 keeps below 1 for a wider
   spread of ``H_t / H``.

What a lab reads of an iteration (:func:`iteration_errors`): the rms error in the band as a share
of the target's rms there, the same per ISO 266 octave, the share of samples whose error lies inside
the target's own 95 % band, and the damage ratio rig / road (:func:`damage_ratio`): Miner's sum of
the rainflow cycles (ASTM E1049-85, the ``rainflow`` package) of the response and of the target,
each cycle weighted by its range to the S-N exponent ``m`` (Basquin: ``N ~ S^-m``), so the ratio
needs no S-N curve's constant.

Spectra are taken over the whole record with a DFT zero-padded by :data:`PADDING_S`, so that a drive
computed from a target of the same length does not wrap its response round.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import rainflow

from bench.analysis.flags import FlagCode, flag
from bench.analysis.plate_mass import base_acceleration_signal
from bench.analysis.records import DISPLACEMENT, HUB_ACCELERATION, PLATE_FORCE, WFS_FORCE
from bench.analysis.road_validation import OCTAVE_CENTRES_HZ, band_limited, band_rms, octave_band
from sequences.steps import IDENTIFICATION_SHAPES

#: The channels (standard names) each response is computed from, and the SI unit it is in.
RESPONSE_CHANNELS = {
    "contact_force": (PLATE_FORCE, DISPLACEMENT),
    "wfs_force": (WFS_FORCE,),
    "hub_acceleration": (HUB_ACCELERATION,),
    "post_force": (PLATE_FORCE,),
}
RESPONSE_UNITS = {"contact_force": "N", "wfs_force": "N", "hub_acceleration": "m/s^2", "post_force": "N"}
#: Welch segment of the FRF estimate (s): 0.25 Hz resolution.
FRF_SEGMENT_S = 4.0
#: Rest appended to a drive's DFT (s) so that the rig's response to it does not wrap round.
PADDING_S = 2.0


@dataclass(frozen=True)
class Frf:
    """The rig's frequency response from drive (mm) to the matched response (its unit per mm) at
    ``freq_hz``, and the coherence of that estimate."""

    freq_hz: np.ndarray
    h: np.ndarray
    coherence: np.ndarray


def broadband_drive(
    shape: str,
    *,
    rms_mm: float,
    duration_s: float,
    sample_rate_hz: float,
    band_hz: tuple[float, float],
    seed: int,
    target: np.ndarray | None = None,
) -> np.ndarray:
    """A Gaussian drive (mm) of ``rms_mm`` over ``band_hz``: ``pink`` (density ~ 1/f) or ``shaped``
    like ``target``'s Welch density; nothing outside the band. Seeded: the same arguments give the
    same samples."""
    if shape not in IDENTIFICATION_SHAPES:
        raise ValueError(f"broadband shape {shape!r}: one of {', '.join(IDENTIFICATION_SHAPES)}")
    n = round(duration_s * sample_rate_hz) + 1
    rng = np.random.default_rng(seed)
    spectrum = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1 / sample_rate_hz)
    inside = (f >= band_hz[0]) & (f <= band_hz[1]) & (f > 0)
    amplitude = np.zeros_like(f)
    if shape == "pink":
        amplitude[inside] = 1 / np.sqrt(f[inside])
    else:
        if target is None:
            raise ValueError("a shaped drive needs the target whose density it follows")
        from scipy.signal import welch  # loaded where the analysis first needs it

        segment = _segment(target.size, sample_rate_hz)
        ft, psd = welch(target - np.mean(target), fs=sample_rate_hz, nperseg=segment)
        amplitude[inside] = np.sqrt(np.interp(f[inside], ft, psd))
    x = np.fft.irfft(spectrum * amplitude, n)
    return x * (rms_mm / np.sqrt(np.mean(x**2)))


def compared_span(
    n_samples: int, fs_hz: float, taper_in_s: float, taper_out_s: float, settle_s: float
) -> slice:
    """The samples of a drive of ``n_samples`` where its response is compared with the target and
    corrected: between its tapers, less ``settle_s`` at each end (the tapers' transients)."""
    return slice(round((taper_in_s + settle_s) * fs_hz), n_samples - round((taper_out_s + settle_s) * fs_hz))


def rig_response(
    response: str, channels: Mapping[str, np.ndarray], fs_hz: float, plate_mass_kg: float
) -> np.ndarray:
    """The matched ``response`` from a run's ``channels`` (standard names): the contact force as the
    analysis takes it on the bench, the post's force less its plate's inertia ``F_plate - m_comp
    z''`` (``z''`` by the analysis's double differentiator: NaN in its window at the ends), or a
    channel as recorded."""
    if response == "contact_force":
        a_post = base_acceleration_signal(channels[DISPLACEMENT], fs_hz)
        return np.asarray(channels[PLATE_FORCE], dtype=float) - plate_mass_kg * a_post
    (name,) = RESPONSE_CHANNELS[response]
    return np.asarray(channels[name], dtype=float)


def _segment(n: int, fs_hz: float) -> int:
    return int(min(round(FRF_SEGMENT_S * fs_hz), max(n // 4, 16)))


def estimate_frf(drive_mm: np.ndarray, response: np.ndarray, fs_hz: float) -> Frf:
    """Welch's H1 estimate of the response per mm of drive and its coherence (Hann segments of
    :data:`FRF_SEGMENT_S`, half overlapping)."""
    x = np.asarray(drive_mm, dtype=float)
    y = np.asarray(response, dtype=float)
    if x.size != y.size or x.size < 64:
        raise ValueError(f"drive and response must be one length of at least 64 samples ({x.size}, {y.size})")
    from scipy.signal import csd, welch  # loaded where the analysis first needs it

    nperseg = _segment(x.size, fs_hz)
    f, gxx = welch(x - x.mean(), fs=fs_hz, nperseg=nperseg)
    _, gyy = welch(y - y.mean(), fs=fs_hz, nperseg=nperseg)
    _, gxy = csd(x - x.mean(), y - y.mean(), fs=fs_hz, nperseg=nperseg)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(gxx > 0, gxy / gxx, 0)
        coherence = np.where((gxx > 0) & (gyy > 0), np.abs(gxy) ** 2 / (gxx * gyy), 0.0)
    return Frf(f, h, np.clip(coherence.real, 0.0, 1.0))


def regularised_inverse(frf: Frf, band_hz: tuple[float, float], regularisation: float) -> Frf:
    """The coherence-weighted Tikhonov inverse (module docstring) over ``band_hz``, zero outside;
    ``regularisation``: lambda, relative to the peak of ``|H|^2`` in the band. Its ``coherence`` is
    the FRF's."""
    inside = (frf.freq_hz >= band_hz[0]) & (frf.freq_hz <= band_hz[1])
    power = np.abs(frf.h) ** 2
    floor = regularisation * float(np.max(power[inside])) if inside.any() else 0.0
    g2 = frf.coherence
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = np.where(inside, g2 * np.conj(frf.h) / (g2 * power + floor), 0)
    return Frf(frf.freq_hz, np.nan_to_num(inverse), frf.coherence)


def apply_response(frf: Frf, x: np.ndarray, fs_hz: float) -> np.ndarray:
    """``x`` filtered by the response ``frf`` (interpolated onto the DFT bins of ``x`` zero-padded by
    :data:`PADDING_S`), the same length as ``x``."""
    x = np.asarray(x, dtype=float)
    size = x.size + round(PADDING_S * fs_hz)
    bins = np.fft.rfftfreq(size, 1 / fs_hz)
    real = np.interp(bins, frf.freq_hz, frf.h.real, right=0)
    h = real + 1j * np.interp(bins, frf.freq_hz, frf.h.imag, right=0)
    return np.fft.irfft(np.fft.rfft(x, size) * h, size)[: x.size]


def inverse_drive(inverse: Frf, target: np.ndarray, fs_hz: float) -> np.ndarray:
    """The first drive (mm): the inverse applied to the target's dynamic part."""
    return apply_response(inverse, target - np.mean(target), fs_hz)


def corrected_drive(
    drive_mm: np.ndarray, error: np.ndarray, inverse: Frf, fs_hz: float, gain: float
) -> np.ndarray:
    """The next drive (mm): ``drive + gain * H^-1 error``, the error being target less response."""
    return np.asarray(drive_mm, dtype=float) + gain * apply_response(inverse, error, fs_hz)


def damage(x: np.ndarray, sn_exponent: float) -> float:
    """Miner's relative damage of ``x``: the sum over its rainflow cycles of count x range^m (the
    S-N curve's constant cancels in a ratio)."""
    cycles = rainflow.count_cycles(np.asarray(x, dtype=float))
    return float(sum(count * rng**sn_exponent for rng, count in cycles))


def damage_ratio(response: np.ndarray, target: np.ndarray, sn_exponent: float) -> float:
    """The rig's damage over the road's, of the response and the target (one span, one unit)."""
    road = damage(target, sn_exponent)
    return damage(response, sn_exponent) / road if road > 0 else float("nan")


@dataclass(frozen=True)
class IterationErrors:
    """One iteration's response against the target over the span compared, both in ``band_hz``:
    ``rms_error_pct`` of the target's rms there, ``octave_error_pct`` per octave of
    :data:`OCTAVE_CENTRES_HZ` (of the target's whole rms in the band, so the octaves' squares add up
    to the whole's), ``in_band_fraction`` of samples whose error lies inside the target's 95 % band
    (None: the target has none), and the ``damage_ratio`` rig / road at ``sn_exponent``."""

    rms_error_pct: float
    octave_error_pct: tuple[float, ...]
    in_band_fraction: float | None
    damage_ratio: float
    target_rms: float
    error_rms: float


def stop_rules_met(errors: IterationErrors, rms_error_pct: float, in_band_pct: float) -> bool:
    """A drive iteration's stop rules: the rms error below ``rms_error_pct`` and, where the target
    has a band, at least ``in_band_pct`` % of the samples inside it."""
    inside = errors.in_band_fraction is None or 100 * errors.in_band_fraction >= in_band_pct
    return errors.rms_error_pct < rms_error_pct and inside


def iteration_errors(
    response: np.ndarray,
    target: np.ndarray,
    fs_hz: float,
    band_hz: tuple[float, float],
    *,
    sn_exponent: float,
    u95: np.ndarray | None = None,
) -> IterationErrors:
    """:class:`IterationErrors` of ``response`` against ``target`` (one span; their means removed)."""
    y = np.asarray(response, dtype=float) - np.mean(response)
    t = np.asarray(target, dtype=float) - np.mean(target)
    error = y - t
    target_rms = band_rms(t, fs_hz, band_hz)
    error_rms = band_rms(error, fs_hz, band_hz)
    octaves = []
    for centre in OCTAVE_CENTRES_HZ:
        lo, hi = octave_band(centre)
        octaves.append(100 * band_rms(error, fs_hz, (max(lo, band_hz[0]), min(hi, band_hz[1]))) / target_rms)
    inside = None
    if u95 is not None:
        limited = band_limited(error, fs_hz, band_hz)
        inside = float(np.mean(np.abs(limited) <= np.asarray(u95, dtype=float)))
    in_band = (band_limited(y, fs_hz, band_hz), band_limited(t, fs_hz, band_hz))
    return IterationErrors(
        rms_error_pct=100 * error_rms / target_rms,
        octave_error_pct=tuple(octaves),
        in_band_fraction=inside,
        damage_ratio=damage_ratio(in_band[0], in_band[1], sn_exponent),
        target_rms=target_rms,
        error_rms=error_rms,
    )


#: Samples of each trace an iteration's result keeps for its figure (the hold, decimated to this).
TRACE_POINTS = 4000


@dataclass(frozen=True)
class IterationResult:
    """One drive of a drive iteration analysed (iteration 1 on; the identification is not compared):
    its step's run id ``step_run_id`` and ``iteration``, the ``response`` matched (its ``unit``)
    against ``target_source``, the drive's ``drive_crc32``, the band and S-N exponent, the
    :class:`IterationErrors`' figures over the drive's hold, and ``traces``: ``t_s`` (s from the
    drive's start), ``target`` and ``response`` (their means removed, limited to the band) over the
    hold, decimated to at most :data:`TRACE_POINTS`. ``stop_rules_met``: the step's stop rules hold
    here; ``last``: the step's largest count of iterations was reached here."""

    step_run_id: str
    iteration: int
    response: str
    unit: str
    target_source: str
    drive_crc32: str
    band_hz: tuple[float, float]
    sn_exponent: float
    rms_error_pct: float
    octave_error_pct: tuple[float, ...]
    in_band_pct: float | None
    damage_ratio: float
    target_rms: float
    error_rms: float
    stop_rules_met: bool
    last: bool
    traces: dict[str, np.ndarray]

    def summary_lines(self) -> list[str]:
        """The text report: the iteration's errors against its target."""
        octaves = " / ".join(f"{c:g}" for c in OCTAVE_CENTRES_HZ)
        per_octave = " / ".join(f"{x:.3g}" for x in self.octave_error_pct)
        band = (
            "" if self.in_band_pct is None else f"; inside the target's 95 % band: {self.in_band_pct:.1f} %"
        )
        matched = self.response.replace("_", " ")
        lo, hi = self.band_hz
        return [
            f"drive iteration {self.step_run_id}, iteration {self.iteration}: {matched}"
            f" against {self.target_source} (drive CRC-32 {self.drive_crc32})",
            f"rms error in {lo:g}-{hi:g} Hz: {self.rms_error_pct:.2f} % of the target's"
            f" {self.target_rms:.4g} {self.unit} rms{band}",
            f"error per octave at {octaves} Hz: {per_octave} % of the target's rms",
            f"damage ratio rig / road (rainflow, S-N exponent {self.sn_exponent:g}): {self.damage_ratio:.3f}",
            *self._stop_lines(),
        ]

    def _stop_lines(self) -> list[str]:
        if self.stop_rules_met:
            return ["the step's stop rules hold: the iteration ends here"]
        if self.last:
            text = f"the stop rules do not hold after the step's largest count, {self.iteration} iterations"
            return [flag(FlagCode.NOT_CONVERGED, text)]
        return []


def analyse_iteration(
    channels: Mapping[str, np.ndarray],
    target: np.ndarray,
    u95: np.ndarray | None,
    *,
    fs_hz: float,
    hold: slice,
    response: str,
    plate_mass_kg: float,
    band_hz: tuple[float, float],
    sn_exponent: float,
) -> tuple[IterationErrors, dict[str, np.ndarray]]:
    """The response of a run's ``channels`` over the drive (sample 0: the drive's first) against
    ``target`` over ``hold``: the errors and the traces (module docstring)."""
    y = rig_response(response, channels, fs_hz, plate_mass_kg)
    if y.size < hold.stop:
        raise ValueError(f"the run recorded {y.size} samples of the drive's {target.size}")
    y, t = y[hold], np.asarray(target, dtype=float)[hold]
    if not np.all(np.isfinite(y)):
        raise ValueError("the response is not finite over the drive's hold")
    errors = iteration_errors(
        y, t, fs_hz, band_hz, sn_exponent=sn_exponent, u95=None if u95 is None else u95[hold]
    )
    step = max(1, -(-y.size // TRACE_POINTS))
    traces = {
        "t_s": (hold.start + np.arange(y.size))[::step] / fs_hz,
        "target": band_limited(t - t.mean(), fs_hz, band_hz)[::step],
        "response": band_limited(y - y.mean(), fs_hz, band_hz)[::step],
    }
    return errors, traces


def by_step(results: Mapping[str, IterationResult]) -> dict[str, list[tuple[str, IterationResult]]]:
    """Drive iterations' results (by run id) grouped by their step's run id, each step's runs in
    iteration order: what the JSON and the report show per step."""
    steps: dict[str, list[tuple[str, IterationResult]]] = {}
    for run_id, result in results.items():
        steps.setdefault(result.step_run_id, []).append((run_id, result))
    return {step: sorted(runs, key=lambda item: item[1].iteration) for step, runs in steps.items()}
