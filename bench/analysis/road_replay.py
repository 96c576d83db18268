"""A road replay on the four-post bench analysed: the WFS force as measured (raw), compensated with
the hub acceleration and compensated with the identified model, each against the post's contact
force, in time and as spectra (docs/analysis.md, *Road replay*).

The reference is what the bench measures of the contact force, the post's plate force corrected
for the plate's inertia, ``F_contact = F_plate - m_comp z''`` with the post's m_comp (its free run)
and ``z''`` from its displacement. The forces compared are their dynamic parts: each less its mean
over the span compared (the static load on the plate, the WFS's tare, are no dynamics). The span is
where every filter (the differentiator, the compensation's FIRs) is defined: the drive less the
filters' windows at its ends.

Figures: the rms error of each force in 0-30 Hz and per octave
(:func:`~bench.analysis.road_validation.force_errors`: Parseval over the DFT bins), the contact
force's rms there, the power spectral densities (Welch) of the forces and of their errors, and a
stretch of the forces in time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.compensation import advance_acceleration, hub_acceleration_compensation
from bench.analysis.measurement_compensation import CompensationFilters, CompensationStream
from bench.analysis.plate_mass import PlateMass, base_acceleration_signal
from bench.analysis.records import (
    DISPLACEMENT,
    HUB_ACCELERATION,
    PLATE_FORCE,
    WFS_FORCE,
    WHEEL_CHANNELS,
    RoadReplayRecord,
    record_channels,
)
from bench.analysis.road_validation import (
    ERROR_BAND_HZ,
    OCTAVE_CENTRES_HZ,
    ForceErrors,
    band_rms,
    force_errors,
)
from bench.analysis.validation import AnalysisInputError

#: The forces compared with the contact force, in the order reports show them, with their names.
FORCES = (
    ("raw", "raw WFS"),
    ("hub_compensated", "hub-acceleration compensated"),
    ("model_compensated", "model-compensated"),
)
#: Longest Welch segment of the spectra (s): 0.25 Hz bins; a shorter drive gets segments of half
#: its span (three averages with half overlap).
SPECTRUM_SEGMENT_S = 4.0
#: The stretch of the forces kept for a figure (s), from the middle of the span.
TRACE_S = 1.0
#: The shortest span that is analysed (s): a few periods of the lowest octave's centre.
MIN_SPAN_S = 2.0


@dataclass(frozen=True)
class RoadReplayResult:
    """A road replay analysed.

    ``source``: the drive; ``span_s``: the length compared; ``plate_mass_kg`` (the post's m_comp),
    ``wheel_mass_kg`` and ``accelerometer_delay_s`` the corrections used; ``contact_rms_n``: the
    contact force's rms in 0-30 Hz; ``errors``: each force's :class:`ForceErrors` against it by the
    names of :data:`FORCES` (``model_compensated`` absent when the campaign gives no model:
    ``model_omitted`` says why); ``identification`` and ``valid_band_hz``: the model compensation's
    basis and valid band (None without one); ``spectra``: ``freq_hz`` and the power spectral density
    (N^2/Hz) of ``contact`` and of each force and its error (``<name>_error``); ``traces``: ``t_s``
    (s from the drive's start), ``contact`` and each force over :data:`TRACE_S`."""

    source: str
    sample_rate_hz: float
    span_s: float
    plate_mass_kg: float
    wheel_mass_kg: float
    accelerometer_delay_s: float
    contact_rms_n: float
    errors: dict[str, ForceErrors]
    identification: str
    valid_band_hz: tuple[float, float] | None
    model_omitted: str
    spectra: dict[str, np.ndarray]
    traces: dict[str, np.ndarray]

    def summary_lines(self) -> list[str]:
        """The text report: the corrections, then each force's rms error in 0-30 Hz and per octave."""
        octaves = " / ".join(f"{c:g}" for c in OCTAVE_CENTRES_HZ)
        lines = [
            f"road replay of {self.source}: {self.span_s:.1f} s compared at {self.sample_rate_hz:g} Hz",
            f"contact force: post force less m_comp {self.plate_mass_kg:.3f} kg x z''; its rms in"
            f" {ERROR_BAND_HZ[0]:g}-{ERROR_BAND_HZ[1]:g} Hz {self.contact_rms_n:.4g} N",
            f"hub-acceleration compensation: m_wheel {self.wheel_mass_kg:.3f} kg, accelerometer lag"
            f" {1e3 * self.accelerometer_delay_s:.3f} ms",
        ]
        if self.identification:
            lo, hi = self.valid_band_hz
            lines.append(f"model compensation: {self.identification}; valid band {lo:.3g}-{hi:.3g} Hz")
        else:
            lines.append(f"model compensation: none: {self.model_omitted}")
        lines.append(
            f"rms error against the contact force in {ERROR_BAND_HZ[0]:g}-{ERROR_BAND_HZ[1]:g} Hz"
            f" (per octave at {octaves} Hz):"
        )
        for name, label in FORCES:
            if name in self.errors:
                e = self.errors[name]
                per_octave = " / ".join(f"{x:.3g}" for x in e.octave_rms_n)
                lines.append(f"  {label}: {e.rms_n:.4g} N ({per_octave} N)")
        return lines


def _spectra(signals: dict[str, np.ndarray], fs_hz: float) -> dict[str, np.ndarray]:
    from scipy.signal import welch
    n = next(iter(signals.values())).size
    segment = min(round(SPECTRUM_SEGMENT_S * fs_hz), max(n // 2, 16))
    out: dict[str, np.ndarray] = {}
    for name, x in signals.items():
        f, psd = welch(x, fs=fs_hz, nperseg=segment)
        out["freq_hz"], out[name] = f, psd
    return out


def analyse_road_replay(
    record: RoadReplayRecord,
    *,
    plate: PlateMass,
    wheel_mass_kg: float,
    accelerometer_delay_s: float = 0.0,
    filters: CompensationFilters | None = None,
    model_omitted: str = "",
) -> RoadReplayResult:
    """Analyse ``record`` (see the module docstring) with the post's ``plate`` mass, the wheel mass
    and the accelerometer's lag of the hub-acceleration compensation, and ``filters``: the model
    compensation at the record's rate (None: none, ``model_omitted`` says why). AnalysisInputError
    naming the record when its channels are missing or not finite, or too short a span is left."""
    fs = float(record.sample_rate_hz)
    rec = record_channels(record, WHEEL_CHANNELS, min_samples=64)
    a_post = base_acceleration_signal(rec[DISPLACEMENT], fs)
    forces = {"contact": rec[PLATE_FORCE] - plate.mass_kg * a_post, "raw": rec[WFS_FORCE]}
    a_hub = rec[HUB_ACCELERATION] - np.mean(rec[HUB_ACCELERATION])  # a hub does not accelerate on average
    advanced = advance_acceleration(a_hub, fs, accelerometer_delay_s)
    forces["hub_compensated"] = hub_acceleration_compensation(rec[WFS_FORCE], advanced, wheel_mass_kg)
    if filters is not None:
        blocks = CompensationStream(filters).blocks(rec[WFS_FORCE], a_hub)
        forces["model_compensated"] = np.concatenate([b.force_n for b in blocks])
    defined = np.flatnonzero(np.logical_and.reduce([np.isfinite(x) for x in forces.values()]))
    if defined.size < MIN_SPAN_S * fs:
        raise AnalysisInputError(
            f"{record.label}: {defined.size / fs:.2f} s where every filter is defined, at least"
            f" {MIN_SPAN_S:g} s needed: a longer drive"
        )
    span = slice(int(defined[0]), int(defined[-1]) + 1)
    dynamic = {name: x[span] - np.mean(x[span]) for name, x in forces.items()}
    contact = dynamic["contact"]
    names = [name for name, _ in FORCES if name in dynamic]
    errors = {name: force_errors(dynamic[name], contact, fs) for name in names}
    spectra = _spectra(
        {
            "contact": contact,
            **{n: dynamic[n] for n in names},
            **{f"{n}_error": dynamic[n] - contact for n in names},
        },
        fs,
    )
    middle = (span.stop - span.start) // 2
    shown = slice(max(middle - round(TRACE_S * fs / 2), 0), middle + round(TRACE_S * fs / 2))
    traces = {"t_s": (span.start + np.arange(span.stop - span.start)[shown]) / fs}
    traces |= {name: x[shown] for name, x in dynamic.items()}
    basis = None if filters is None else filters.basis
    return RoadReplayResult(
        source=record.source or "a drive",
        sample_rate_hz=fs,
        span_s=(span.stop - span.start) / fs,
        plate_mass_kg=plate.mass_kg,
        wheel_mass_kg=float(wheel_mass_kg),
        accelerometer_delay_s=float(accelerometer_delay_s),
        contact_rms_n=band_rms(contact, fs, ERROR_BAND_HZ),
        errors=errors,
        identification="" if basis is None else basis.label,
        valid_band_hz=None if basis is None else basis.valid_band_hz,
        model_omitted=model_omitted if filters is None else "",
        spectra=spectra,
        traces=traces,
    )
