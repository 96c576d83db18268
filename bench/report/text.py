"""The analysis results as short text reports: one line per finding, units on every number, an
explicit line for whatever is not determined and a ``FLAG`` line for whatever is flagged (an
unsettled or rejected dwell, unreliable bins, a fit that did not converge).

:func:`summary_lines` takes any result of :mod:`bench.analysis.runs` (or a hammer result); the
per-type functions are its parts.
"""

from __future__ import annotations

import numpy as np

from bench.analysis.flags import FlagCode, flag
from bench.analysis.frf import ValidBand
from bench.analysis.hammer import DAMPING_AGREEMENT, HammerResult
from bench.analysis.lsq import Z95
from bench.analysis.repeats import RepeatSpread
from bench.analysis.runs import (
    FourPostResult,
    FreeRunResult,
    ShakerAmplitudeResult,
    ShakerCampaignResult,
    ShakerRatiosResult,
)


def band_text(band: ValidBand) -> str:
    """A valid band with where it starts, why it ends and the unreliable points it skips."""
    if band.n_points == 0:
        return f"none (fails at {band.lowest_hz:.4g} Hz: {band.limited_by})"
    if not band.determined:
        return f"not determined (only {band.lowest_hz:.4g} Hz passes, then {band.limited_by})"
    skipped = f"; skips unreliable {ranges_text(np.array(band.skipped_hz))}" if band.skipped_hz else ""
    return (
        f"{band.lowest_hz:.4g}-{band.upper_hz:.4g} Hz (starts: {band.starts_at};"
        f" ends: {band.limited_by}{skipped})"
    )


def ranges_text(freq_hz: np.ndarray, step_hz: float | None = None) -> str:
    """Frequencies as ranges of neighbouring points (``step_hz`` apart; default: the smallest
    spacing): ``0.122-2.2 Hz, 29.9 Hz``."""
    f = np.sort(np.asarray(freq_hz, dtype=float))
    if f.size == 0:
        return "none"
    step = step_hz or (float(np.min(np.diff(f))) if f.size > 1 else 1.0)
    breaks = np.flatnonzero(np.diff(f) > 1.5 * step) + 1
    runs = np.split(f, breaks)
    return ", ".join(f"{r[0]:.4g} Hz" if r.size == 1 else f"{r[0]:.4g}-{r[-1]:.4g} Hz" for r in runs)


def tolerance_text(band: ValidBand) -> str:
    """The tolerances a valid band was judged against."""
    return f"| |H|-1 | <= {100 * band.amplitude_tolerance:g} %, |phase| <= {band.phase_tolerance_deg:g} deg"


def values_text(values: dict[str, float], ci95: dict[str, float]) -> str:
    """Fitted values with their 95 % half-widths."""
    return ", ".join(f"{name} {v:.6g} +/- {ci95[name]:.2g}" for name, v in values.items())


def repeats_lines(prefix: str, repeats: tuple[RepeatSpread, ...]) -> list[str]:
    """The dwells measured more than once: the repeatability (the largest spread), each repeated
    point's spread per channel against its noise, and a ``FLAG`` where the spread is far outside
    it. ``prefix`` names the grid (``2 mm ``, ``free run ``)."""
    if not repeats:
        return []
    worst = max(repeats, key=lambda r: r.largest[1])
    channel, spread = worst.largest
    lines = [
        f"{prefix}repeatability: {len(repeats)} dwell(s) measured more than once, each combined into one"
        f" point; largest spread {100 * spread:.2g} % rms ({channel} over the displacement, {worst.label})"
    ]
    for r in repeats:
        per = ", ".join(f"{c} {100 * v:.2g} % (noise {100 * r.noise[c]:.2g} %)" for c, v in r.spread.items())
        lines.append(f"{prefix}repeats: {r.label}: {r.n} combined; spread over the displacement: {per}")
        if r.outside_noise:
            lines.append(
                flag(
                    FlagCode.REPEATS_DIFFER,
                    f"{prefix}repeats of {r.label} differ far outside their noise: the specimen or the"
                    " bench changed between them (tyre pressure or temperature, a clamp)",
                )
            )
    return lines


def hammer_lines(result: HammerResult) -> list[str]:
    """The sensor from a hammer blow; the two damping estimates are flagged when they disagree by
    more than ``DAMPING_AGREEMENT`` (they are independent: one of them is then not to be trusted)."""
    lines = [
        f"hammer: eigenfrequency {result.eigenfrequency_hz:.1f} Hz"
        f" (damped {result.damped_frequency_hz:.1f} Hz), free decay"
        f" {1e3 * result.decay_start_s:.1f}-{1e3 * result.decay_stop_s:.1f} ms, {result.n_peaks} peaks",
        f"damping ratio: half-power {result.damping_ratio_half_power:.4f},"
        f" logarithmic decrement {result.damping_ratio_log_decrement:.4f}",
        f"from the sensor mass: stiffness {result.stiffness_n_per_m:.4g} N/m,"
        f" damping {result.damping_ns_per_m:.4g} Ns/m",
    ]
    if result.damping_ratio_disagreement > DAMPING_AGREEMENT:
        lines.append(
            flag(
                FlagCode.DAMPING_DISAGREES,
                f"the damping ratios disagree by {100 * result.damping_ratio_disagreement:.0f} %"
                f" (more than {100 * DAMPING_AGREEMENT:.0f} %): check the decay (noise, a second mode)",
            )
        )
    return lines


def free_run_lines(result: FreeRunResult) -> list[str]:
    """m_comp with the dwells it comes from, and every dwell left out; a nominal m_comp says whose
    it is."""
    p = result.plate
    if result.nominal:
        return [
            flag(
                FlagCode.NOMINAL_M_COMP,
                f"m_comp {p.mass_kg:g} kg nominal ({result.nominal_source}): not measured, no free run",
            )
        ]
    lines = [
        f"m_comp {p.mass_kg:.4f} +/- {Z95 * p.sigma_kg:.1g} kg (95 %) from {p.n_points} of"
        f" {len(result.fits)} free-run dwells {result.fits[0].freq_hz:g}-{result.fits[-1].freq_hz:g} Hz"
        f" (residual {p.residual_rms_n_per_m:.3g} N/m rms)"
    ]
    lines += repeats_lines("free run ", result.repeats)
    lines += [flag(FlagCode.NOT_SETTLED, f"free run not settled: {u}") for u in result.unsettled]
    lines += [flag(FlagCode.REJECTED, f"free run rejected: {r}") for r in result.rejected]
    lines += [flag(FlagCode.FREE_RUN, f"free run: {finding}") for finding in result.findings]
    return lines


def shaker_amplitude_lines(result: ShakerAmplitudeResult) -> list[str]:
    """One amplitude: the model selected and why, its parameters, what no model determines, the
    peak of the ratio, the valid bands, and every flag."""
    ident = result.identification
    best = ident.best_fit
    label = result.label
    bics = ", ".join(f"Model {int(m)} {f.bic:.1f}" for m, f in ident.fits.items())
    rise = "fitted" if ident.frequency_dependent_stiffness else "not needed"
    hysteretic = "fitted" if ident.hysteretic_damping else "not needed"
    rubber = f"stiffness rise with frequency {rise}, hysteretic damping {hysteretic}"
    lines = [
        f"{label}: {len(result.fits)} dwells {result.fits[0].freq_hz:g}-{result.fits[-1].freq_hz:g} Hz;"
        f" Model {int(ident.best)} selected ({ident.selection}; BIC {bics});"
        f" {rubber}",
        f"{label} Model {int(ident.best)} (95 %): {values_text(best.values, best.ci95)};"
        f" F_wfs/F_contact rms error {100 * best.ratio_relative_rms:.2f} %",
    ]
    missing = "; ".join(
        f"Model {int(model)}: {', '.join(fit.undetermined)}"
        for model, fit in ident.fits.items()
        if fit.undetermined
    )
    lines.append(f"{label} not determined: {missing or 'none'}")
    for model, fit in ident.fits.items():
        if not fit.converged:
            not_converged = f"{label} Model {int(model)}: the fit did not converge"
            lines.append(flag(FlagCode.FIT_NOT_CONVERGED, not_converged))
    lines += [flag(FlagCode.IDENTIFICATION, f"{label}: {finding}") for finding in ident.findings]
    if result.model_peak is not None:
        p = result.model_peak
        top_hz, top = result.largest_measured_ratio
        lines.append(
            f"{label} |F_wfs/F_contact| peak of Model {int(ident.best)}: {p.height:.3g} +/-"
            f" {p.height_ci95:.2g} at {p.freq_hz:.4g} +/- {p.freq_ci95_hz:.2g} Hz (95 %); largest"
            f" measured {top:.3g} at {top_hz:g} Hz"
        )
    lines.append(
        f"{label} valid band ({tolerance_text(result.valid_band_raw)}):"
        f" raw {band_text(result.valid_band_raw)},"
        f" model-compensated {band_text(result.valid_band_compensated)}"
        f" (compensator design error {100 * result.compensator.design_error:.2f} %)"
    )
    lines += [f"{label} model-compensated band {condition}" for condition in result.band_conditions]
    lines += repeats_lines(f"{label} ", result.repeats)
    if not result.hub_acceleration_recorded:
        lines.append(
            f"{label} no hub-acceleration channel: the clamped hub is taken as not moving (the"
            " model-compensated ratio without its hub-acceleration term); whether it moved is not checked"
        )
    lines += [flag(FlagCode.NOT_SETTLED, f"not settled: {u}") for u in result.unsettled]
    lines += [flag(FlagCode.REJECTED, f"rejected: {r}") for r in result.rejected]
    return lines


def shaker_ratios_lines(result: ShakerRatiosResult) -> list[str]:
    """An amplitude too small for a tyre fit: why, then each dwell's measured F_wfs/F_contact with
    95 % intervals of its magnitude and phase (a complex standard uncertainty ``sigma`` gives each
    component ``sigma / sqrt 2``), and the raw valid band."""
    label, raw = result.label, result.frfs.wfs_per_contact
    lines = [
        f"{label}: {len(result.fits)} dwells {result.fits[0].freq_hz:g}-{result.fits[-1].freq_hz:g} Hz;"
        f" no tyre fit: {result.why}; the measured F_wfs/F_contact (95 %):"
    ]
    for f, h, sigma, ok in zip(raw.freq_hz, raw.value, raw.sigma, raw.reliable, strict=True):
        half = Z95 * sigma / np.sqrt(2)
        note = "" if ok else " (not reliable: not settled)"
        lines.append(
            f"{label} {f:g} Hz: |F_wfs/F_contact| {abs(h):.4g} +/- {half:.2g}, phase"
            f" {np.degrees(np.angle(h)):.2f} +/- {np.degrees(half / abs(h)):.2g} deg{note}"
        )
    band = result.valid_band_raw
    lines.append(f"{label} valid band ({tolerance_text(band)}): raw {band_text(band)}")
    lines += repeats_lines(f"{label} ", result.repeats)
    if not result.hub_acceleration_recorded:
        lines.append(f"{label} no hub-acceleration channel (the clamped hub needs none)")
    lines += [flag(FlagCode.NOT_SETTLED, f"not settled: {u}") for u in result.unsettled]
    lines += [flag(FlagCode.REJECTED, f"rejected: {r}") for r in result.rejected]
    return lines


def shaker_campaign_lines(result: ShakerCampaignResult) -> list[str]:
    """A tyre's shaker campaign: the givens, m_comp, every amplitude (those too small for a fit with
    their measured ratios) and the amplitude dependence."""
    amps = ", ".join(r.label for r in (*result.amplitudes.values(), *result.ratios_only.values()))
    lines = [
        f"shaker campaign: amplitudes {amps}; wheel mass {result.wheel_mass_kg:g} kg (given),"
        f" sensor {result.sensor.mass_kg:g} kg at {result.sensor.eigenfrequency_hz:g} Hz, damping ratio"
        f" {result.sensor.damping_ratio:.3g} ({result.sensor_source})",
        *free_run_lines(result.free_run),
    ]
    for amplitude in result.amplitudes.values():
        lines += shaker_amplitude_lines(amplitude)
    for ratios in result.ratios_only.values():
        lines += shaker_ratios_lines(ratios)
    dep = result.amplitude_dependence
    if dep is None:
        why = "one amplitude only" if result.amplitudes else "no amplitude with a tyre fit"
        lines.append(f"amplitude dependence: not determined ({why})")
    else:
        per = "; ".join(
            f"{1e3 * a:g} mm k {k / 1e3:.2f} +/- {ci / 1e3:.2f} kN/m ({100 * dk:+.2f} %),"
            f" d {d:.1f} Ns/m ({100 * dd:+.1f} %)"
            for a, k, ci, dk, d, dd in dep.rows()
        )
        lines.append(f"amplitude dependence (Model 2, d at the tread resonance; change vs smallest): {per}")
    return lines


def four_post_lines(result: FourPostResult) -> list[str]:
    """A four-post sweep: the post's m_comp, m_wheel, the valid bands, the quarter car and its
    modes, what it does not determine or took as given, and the unreliable bins."""
    m, car, s = result.wheel_mass, result.quarter_car, result.quarter_car.suspension
    lines = [
        f"four-post {result.label}; tyre: Model {int(result.tyre_model)} from {result.tyre_source}",
        *(f"post {line}" for line in free_run_lines(result.post_free_run)),
        f"m_wheel {m.mass_kg:.3f} +/- {Z95 * m.sigma_kg:.2g} kg (95 %) from the run"
        f" ({m.band_hz[0]:.3g}-{m.band_hz[1]:.3g} Hz; weighed {result.wheel_mass_given_kg:g} kg,"
        f" {100 * (m.mass_kg / result.wheel_mass_given_kg - 1):+.1f} %),"
        f" accelerometer lag {1e3 * m.accelerometer_delay_s:.3f} ms",
        f"sweep displacement amplitude: measured {1e3 * result.measured_amplitude_m:.3g} mm, declared"
        f" {1e3 * result.amplitude_m:g} mm",
        f"valid band ({tolerance_text(result.valid_band_raw)}): raw {band_text(result.valid_band_raw)},"
        f" hub-acceleration compensated {band_text(result.valid_band_hub_compensated)},"
        f" model-compensated {band_text(result.valid_band_model_compensated)}",
        f"quarter car (95 %): {values_text(car.values, car.ci95)}; reduced chi^2 {car.reduced_chi2:.1f}"
        f" over {car.band_hz[0]:.4g}-{car.band_hz[1]:.4g} Hz",
        f"modes: body {car.body_frequency_hz:.3f} +/- {car.body_frequency_ci95_hz:.3f} Hz"
        f" (damping ratio {car.body_damping_ratio:.3f}), wheel {car.wheel_frequency_hz:.2f}"
        f" +/- {car.wheel_frequency_ci95_hz:.2f} Hz (damping ratio {car.wheel_damping_ratio:.3f});"
        f" unsprung mass above the sensor {s.unsprung_mass_above_kg:.2f} kg",
        f"quarter car not determined: {', '.join(car.undetermined) or 'none'}",
        f"quarter car taken as given: {'; '.join(car.taken_as_given)}",
    ]
    if result.unreliable_bins:
        f = result.frfs.wfs_per_z.freq_hz
        flank_hz, other_hz = result.unreliable_bins_hz
        step = float(f[1] - f[0]) if f.size > 1 else None
        lines.append(
            flag(
                FlagCode.UNRELIABLE_BINS,
                f"{result.unreliable_bins} of {f.size} bins in {f[0]:.3g}-{f[-1]:.3g} Hz unreliable"
                f" over Z and not used by the quarter car: on the sweep's flanks"
                f" {ranges_text(flank_hz, step)}"
                f" (biased over Z, usable in the force ratios); low excitation or coherence"
                f" {ranges_text(other_hz, step)}",
            )
        )
    if not car.converged:
        lines.append(flag(FlagCode.FIT_NOT_CONVERGED, "the quarter-car fit did not converge"))
    lines += [flag(FlagCode.IDENTIFICATION, finding) for finding in result.findings]
    return lines


_RENDERERS = (
    (HammerResult, hammer_lines),
    (FreeRunResult, free_run_lines),
    (ShakerAmplitudeResult, shaker_amplitude_lines),
    (ShakerCampaignResult, shaker_campaign_lines),
    (FourPostResult, four_post_lines),
)


def summary_lines(
    result: HammerResult | FreeRunResult | ShakerAmplitudeResult | ShakerCampaignResult | FourPostResult,
) -> list[str]:
    """The short text report of any analysis result."""
    for kind, render in _RENDERERS:
        if isinstance(result, kind):
            return render(result)
    raise TypeError(f"no text report for {type(result).__name__}")
