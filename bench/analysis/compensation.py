"""Compensation of the WFS force to the contact force: the paper's hub-acceleration term and a
model-based inverse that also corrects the tread dynamics.

Hub acceleration (paper, section 5): ``F_contact ~ F_wfs + m_wheel a_hub``. ``m_wheel`` can be given
or estimated from a run where the contact force is measured (four-post), by least squares on
band-passed signals: ``F_contact - F_wfs = m_rim a_hub (+ m_contact a_contact)``; the second
regressor, the contact-patch acceleration from the post's displacement, separates the mass that
moves with the contact (the tread) so that ``m_wheel = m_rim + m_contact`` is not biased by it. A
third regressor, the derivative of the measured hub acceleration, absorbs a small lag of the
accelerometer against the force channels (``a(t) ~ a_meas(t) + tau a_meas'(t)``; a mass-production
sensor's low-pass or a separate acquisition path): without it the lag leaks into the masses.
:func:`advance_acceleration` removes that lag before compensating.

Model-based: below the sensor the tyre/wheel is linear in the contact displacement ``Z`` and the hub
displacement ``z_h``::

    F_wfs = P Z + Q z_h,   F_contact = R Z + S z_h

(``P, R`` from :func:`~bench.analysis.shaker_models.shaker_response`, ``Q, S`` from
:func:`~bench.analysis.shaker_models.hub_driven_response``). Eliminating the unmeasured ``Z`` with
``z_h = -a_hub / w^2``::

    F_contact = G_F F_wfs + G_A a_hub,   G_F = R / P,   G_A = -(S - R Q / P) / w^2

independent of what stands above the sensor. ``G_F`` is the inverse of the tread resonance (it
nearly vanishes where the contact force does) and grows as ``m_T w / d`` far above the band, so it
is realised as two FIR filters designed by relative-weighted complex least squares over the band,
rolled off to zero above it, with a fixed latency: stable, causal and streamable.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bench.analysis.fir import (
    STOP_BAND_FACTOR,
    StreamingFir,
    apply_aligned,
    design_fir,
    fir_response,
    half_cosine_rolloff,
)
from bench.analysis.shaker_models import LINEAR, RubberTerms, hub_driven_response, shaker_response
from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signals
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor


def hub_acceleration_compensation(f_wfs: np.ndarray, a_hub: np.ndarray, wheel_mass_kg: float) -> np.ndarray:
    """``F_wfs + m_wheel a_hub`` (signals or phasors alike)."""
    return np.asarray(f_wfs) + wheel_mass_kg * np.asarray(a_hub)


@dataclass(frozen=True)
class WheelMass:
    """Mass below the sensor from a run: ``mass_kg`` (m_wheel, used by the hub-acceleration
    compensation) with standard uncertainty ``sigma_kg``; ``rim_side_kg`` multiplies the hub
    acceleration, ``contact_side_kg`` the contact acceleration (0 when not estimated);
    ``explained_fraction``: share of the force difference's variance the fit explains;
    ``accelerometer_delay_s``: the lag of the hub acceleration behind the forces (0 when not fitted)."""

    mass_kg: float
    sigma_kg: float
    rim_side_kg: float
    contact_side_kg: float
    explained_fraction: float
    accelerometer_delay_s: float
    band_hz: tuple[float, float]


def estimate_wheel_mass(
    f_contact: np.ndarray,
    f_wfs: np.ndarray,
    a_hub: np.ndarray,
    fs_hz: float,
    *,
    a_contact: np.ndarray | None = None,
    band_hz: tuple[float, float] = (1.0, 25.0),
    fit_delay: bool = True,
) -> WheelMass:
    """Least squares of ``F_contact - F_wfs`` on ``a_hub`` (and ``a_contact``), all band-passed
    with the same zero-phase filter (offsets and out-of-band noise removed).

    The uncertainty is :func:`_coloured_noise_covariance`: the band-passed residual is strongly
    correlated from sample to sample, so the white-noise ``s^2 (X'X)^-1`` would be far too small,
    and a flat in-band density is not exact either (the filter's skirts, coloured sensor noise).
    """
    from scipy.signal import butter, sosfiltfilt
    fs = as_sample_rate(fs_hz)
    chans = {"f_contact": f_contact, "f_wfs": f_wfs, "a_hub": a_hub}
    if a_contact is not None:
        chans["a_contact"] = a_contact
    sig = as_signals(chans)
    n_min = int(4 * fs / band_hz[0])
    if sig["a_hub"].size < n_min:
        raise AnalysisInputError(
            f"{sig['a_hub'].size / fs:.4g} s of data are too short for the wheel mass band from"
            f" {band_hz[0]:g} Hz (at least {n_min / fs:.4g} s)"
        )
    sos = butter(4, band_hz, btype="bandpass", fs=fs, output="sos")
    edge = int(2 * fs / band_hz[0])
    filt = {k: sosfiltfilt(sos, v)[edge:-edge] for k, v in sig.items()}
    y = filt["f_contact"] - filt["f_wfs"]
    cols = [filt["a_hub"]]
    if a_contact is not None:
        cols.append(filt["a_contact"])
    if fit_delay:
        cols.append(np.gradient(filt["a_hub"]) * fs)
    X = np.stack(cols, axis=1)
    if np.sqrt(np.mean(X[:, 0] ** 2)) == 0:
        raise AnalysisInputError("no acceleration in the band: the wheel mass cannot be estimated")
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - X @ coef
    cov = _coloured_noise_covariance(X, res, fs)
    n_mass = 2 if a_contact is not None else 1
    total_var = float(np.sum(cov[:n_mass, :n_mass]))
    return WheelMass(
        mass_kg=float(coef[:n_mass].sum()),
        sigma_kg=float(np.sqrt(total_var)),
        rim_side_kg=float(coef[0]),
        contact_side_kg=float(coef[1]) if a_contact is not None else 0.0,
        explained_fraction=float(1 - np.sum(res**2) / np.sum(y**2)),
        accelerometer_delay_s=float(coef[-1] / coef[0]) if fit_delay else 0.0,
        band_hz=band_hz,
    )


def _coloured_noise_covariance(X: np.ndarray, res: np.ndarray, fs: float) -> np.ndarray:
    """Covariance of least-squares coefficients when the error is stationary coloured noise.

    ``cov = (X'X)^-1 X' R X (X'X)^-1`` with ``R`` the error's autocovariance. For stationary noise
    ``X' R X = (1/N) sum_k conj(X_k) X_k^T S_k`` over the DFT bins of the regressors, ``S_k`` the
    noise's two-sided density per sample (``fs/2`` times the one-sided PSD ``G``; white noise of
    variance ``s^2`` gives ``S = s^2`` and the usual ``s^2 (X'X)^-1``). ``G`` is the Welch PSD of the
    residual. For noise flat over a band ``B`` this reduces to ``(X'X)^-1 RSS / (2 B N / fs)``: one
    correction for the band-limiting, not two.
    """
    from scipy.linalg import solve_triangular
    from scipy.signal import welch

    n = X.shape[0]
    f_psd, psd = welch(res, fs=fs, nperseg=min(n, 4096))
    spec = np.fft.rfft(X, axis=0)
    density = np.interp(np.fft.rfftfreq(n, 1 / fs), f_psd, psd) * fs / 2
    density[1 : (n + 1) // 2] *= 2  # bins standing for their negative-frequency twins
    meat = (spec.conj().T * density) @ spec
    r_inv = solve_triangular(np.linalg.qr(X, mode="r"), np.eye(X.shape[1]))
    bread = r_inv @ r_inv.T  # (X'X)^-1 from the QR factor, without squaring X's condition
    return bread @ (meat.real / n) @ bread


def advance_acceleration(a_hub: np.ndarray, fs_hz: float, delay_s: float) -> np.ndarray:
    """``a(t + tau) ~ a(t) + tau a'(t)``: undo a small lag ``tau`` (first order, central differences)."""
    a = np.asarray(a_hub, dtype=float)
    return a + delay_s * np.gradient(a) * as_sample_rate(fs_hz)


def inverse_response(
    model: TyreModel, tyre: Tyre, sensor: WfsSensor, freq_hz: np.ndarray, rubber: RubberTerms = LINEAR
) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``(G_F, G_A)`` of the module docstring at ``freq_hz > 0``."""
    f = np.asarray(freq_hz, dtype=float)
    if np.any(f <= 0):
        raise AnalysisInputError("the inverse is defined for positive frequencies")
    p, r = shaker_response(model, tyre, sensor, f, rubber)
    q, s = hub_driven_response(model, tyre, sensor, f, rubber)
    g_f = r / p
    g_a = -(s - g_f * q) / (2 * np.pi * f) ** 2
    return g_f, g_a


@dataclass(frozen=True)
class ModelCompensator:
    """FIR realisation of the model-based inverse (see the module docstring).

    ``taps_wfs`` and ``taps_accel`` act on ``F_wfs`` (N) and ``a_hub`` (m/s^2); their sum describes the
    contact force ``latency_samples`` samples ago. ``band_hz``: upper end of the design band.
    ``design_error``: largest relative deviation of the FIR from the exact inverse over the band,
    ``max |G_fir - G| / max(|G|, 0.05)`` over both paths (``G_A`` relative to the wheel mass).
    ``accelerometer_delay_s``: the lag of the hub acceleration behind the forces that ``taps_accel``
    undoes (its target ``G_A exp(j w tau)``; 0: none).
    """

    model: TyreModel
    tyre: Tyre
    sensor: WfsSensor
    rubber: RubberTerms
    fs_hz: float
    band_hz: float
    latency_samples: int
    taps_wfs: np.ndarray
    taps_accel: np.ndarray
    design_error: float
    accelerometer_delay_s: float = 0.0

    def response(self, freq_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The filters' responses with the latency removed (compare with :func:`inverse_response`;
        the hub acceleration's includes the advance ``exp(j w accelerometer_delay_s)``)."""
        f = np.asarray(freq_hz, dtype=float)
        shift = np.exp(2j * np.pi * f * self.latency_samples / self.fs_hz)
        return fir_response(self.taps_wfs, f, self.fs_hz) * shift, fir_response(
            self.taps_accel, f, self.fs_hz
        ) * shift

    def apply(self, f_wfs: np.ndarray, a_hub: np.ndarray) -> np.ndarray:
        """Compensated force of a whole record, aligned with the inputs; NaN where the filters'
        window leaves the record: the first ``n_taps - 1 - latency_samples`` samples (no history)
        and the last ``latency_samples`` (they would need future input)."""
        sig = as_signals({"f_wfs": f_wfs, "a_hub": a_hub})
        return apply_aligned(self.taps_wfs, sig["f_wfs"], self.latency_samples) + apply_aligned(
            self.taps_accel, sig["a_hub"], self.latency_samples
        )

    def stream(self) -> StreamingFir:
        """A streaming filter: ``process(f_wfs_block, a_hub_block)``, output delayed by the latency."""
        return StreamingFir([self.taps_wfs, self.taps_accel], self.latency_samples)


def design_model_compensator(
    model: TyreModel,
    tyre: Tyre,
    sensor: WfsSensor,
    rubber: RubberTerms = LINEAR,
    *,
    fs_hz: float = 1000.0,
    band_hz: float = 100.0,
    n_taps: int = 160,
    latency_samples: int = 40,
    accelerometer_delay_s: float = 0.0,
) -> ModelCompensator:
    """Design the two FIR filters of the model-based inverse; the hub acceleration's path also
    undoes the accelerometer's lag ``accelerometer_delay_s`` (target ``G_A exp(j w tau)``).

    In the band the error is weighted relative to the target (``1 / max(|G|, 0.05)^2`` for ``G_F``,
    ``1 / m_wheel^2`` for ``G_A``); above it the target rolls off to zero by a half cosine up to
    ``STOP_BAND_FACTOR band_hz`` and is weighted 1e-3, with a small ridge on the taps: the gain stays bounded.
    """
    fs = as_sample_rate(fs_hz)
    if not 0 < band_hz < fs / 3:
        raise AnalysisInputError(f"compensation band {band_hz} Hz must lie below fs/3")
    f = np.linspace(0, fs / 2, 6 * n_taps + 1)
    f[0] = min(0.01, band_hz / 100)  # the inverse is evaluated just above DC
    g_f, g_a = inverse_response(model, tyre, sensor, f, rubber)
    g_a = g_a * np.exp(2j * np.pi * f * accelerometer_delay_s)
    stop = STOP_BAND_FACTOR * band_hz
    roll = half_cosine_rolloff(f, band_hz, stop)
    outside = np.where(f <= band_hz, 1.0, 1e-3)
    w_f = outside / np.maximum(np.abs(g_f), 0.05) ** 2
    w_a = outside / tyre.wheel_mass_kg**2
    kw = {"n_taps": n_taps, "latency_samples": latency_samples, "fs_hz": fs, "ridge": 1e-6}
    taps_f = design_fir(f, g_f * roll, w_f, **kw)
    taps_a = design_fir(f, g_a * roll, w_a, **kw)
    comp = ModelCompensator(
        model, tyre, sensor, rubber, fs, band_hz, latency_samples, taps_f, taps_a, 0.0, accelerometer_delay_s
    )
    check = f[f <= band_hz]
    r_f, r_a = comp.response(check)
    err = max(
        float(np.max(np.abs(r_f - g_f[f <= band_hz]) / np.maximum(np.abs(g_f[f <= band_hz]), 0.05))),
        float(np.max(np.abs(r_a - g_a[f <= band_hz]) / tyre.wheel_mass_kg)),
    )
    return replace(comp, design_error=err)
