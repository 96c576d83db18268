"""Plate-mass correction of the shaker's load cell (paper, section 2.3).

The free run (no wheel) gives ``F_dyn / Z = -m_comp w^2`` at every dwell frequency; ``m_comp`` is
its weighted least-squares solution over all frequencies::

    m = -sum(w^2 Re(H) / s^2) / sum(w^4 / s^2),   var(m) = 1 / (2 sum(w^4 / s^2))

(``s``: point uncertainty; each of Re, Im has variance s^2/2), inflated by the reduced chi^2 when the
points scatter more than their uncertainty says, as long as the rigid-mass model still describes them.

A free run whose misfit lies beyond any noise (chi^2 of the ``2n`` real residuals over ``2n - 1``
degrees of freedom beyond :func:`~bench.analysis.lsq.chi2_beyond_noise`; the points' uncertainties
are estimates, :func:`~bench.analysis.lsq.chi2_exceedance`) is no rigid plate: the wheel left on
adds the tyre's stiffness ``k - m_T w^2`` to ``F/Z``
(residuals of thousands of sigma). Its m_comp is flagged (:attr:`PlateMass.beyond_noise`) and, like
one merely outside its noise (:attr:`PlateMass.outside_noise`, the test the tyre fits use), keeps
the interval its points' noise gives: the inflation assumes the model holds and the noise was
understated, and an interval inflated by a model error (kilograms) would let the tyre fit, which
takes m_comp's error as common to every ``F_contact/Z`` point, trade m_comp for the tread mass and
fit Model 1 to a tread resonance. With a wheel, the contact force is
``F_contact = F_shaker + m_comp w^2 Z`` in the frequency domain, and ``F_shaker - m_comp z''`` in the
time domain, with ``z''`` from a least-squares FIR double differentiator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bench.analysis.dwell import NOISE_ESTIMATE_DOF, DwellFit, dwell_phasors
from bench.analysis.fir import apply_aligned, double_differentiator
from bench.analysis.frf import Frf, phasor_ratio
from bench.analysis.lsq import chi2_beyond_noise, chi2_far_outside_noise
from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signals


@dataclass(frozen=True)
class PlateMass:
    """``mass_kg`` (m_comp) with its standard uncertainty ``sigma_kg``; ``residual_rms_n_per_m``:
    rms misfit of ``F_dyn / Z`` over the ``n_points`` reliable points used; ``reduced_chi2``: that
    misfit against the points' noise (0 for a mass that was given, not fitted)."""

    mass_kg: float
    sigma_kg: float
    residual_rms_n_per_m: float
    n_points: int
    reduced_chi2: float = 0.0

    @property
    def outside_noise(self) -> bool:
        """The rigid-mass fit misses the free run far outside its noise (a rigid plate does this in
        fewer than 1 of 1000 free runs; see the module docstring). A mass that was given (no
        points) fits nothing."""
        if self.n_points == 0:
            return False
        dof = 2 * self.n_points - 1
        return chi2_far_outside_noise(self.reduced_chi2 * dof, dof, NOISE_ESTIMATE_DOF)

    @property
    def beyond_noise(self) -> bool:
        """No noise explains the misfit (:func:`~bench.analysis.lsq.chi2_beyond_noise`): a free run
        of a rigid plate gives it less than once in a million, a wheel left on every time. Only then
        is m_comp withheld from the runs after it; a misfit merely outside the noise (once in a
        thousand free runs of a good plate) is a finding the user reads."""
        if self.n_points == 0:
            return False
        dof = 2 * self.n_points - 1
        return chi2_beyond_noise(self.reduced_chi2 * dof, dof, NOISE_ESTIMATE_DOF)


def identify_plate_mass(plate_per_z: Frf) -> PlateMass:
    """m_comp from the free-run FRF ``F_plate / Z`` (see the module docstring)."""
    use = plate_per_z.reliable
    if use.sum() < 2:
        raise AnalysisInputError("plate mass needs at least 2 reliable free-run points")
    w2 = (2 * np.pi * plate_per_z.freq_hz[use]) ** 2
    h, s = plate_per_z.value[use], plate_per_z.sigma[use]
    s = np.maximum(s, 1e-9 * np.abs(h))
    mass = -np.sum(w2 * h.real / s**2) / np.sum(w2**2 / s**2)
    resid = h + mass * w2
    n = int(use.sum())
    dof = 2 * n - 1
    chi2 = float(np.sum(2 * np.abs(resid) ** 2 / s**2))
    inflation = 1.0 if chi2_far_outside_noise(chi2, dof, NOISE_ESTIMATE_DOF) else max(chi2 / dof, 1.0)
    sigma = np.sqrt(inflation / (2 * np.sum(w2**2 / s**2)))
    rms = float(np.sqrt(np.mean(np.abs(resid) ** 2)))
    return PlateMass(float(mass), float(sigma), rms, n, chi2 / dof)


@dataclass(frozen=True)
class ShakerErrors:
    """The parts of the shaker FRFs' errors that points share, for a fit that propagates them.

    Per dwell (ascending frequency, as the FRFs): ``wfs_sigma`` and ``plate_sigma``, the
    independent noise of ``F_wfs`` and ``F_shaker`` over ``|Z|`` (N/m); ``displacement_relative_sigma``,
    ``sigma_Z / |Z|``: the displacement's error enters ``F_wfs/Z`` and ``F_contact/Z`` of one dwell
    together. ``plate_mass_kg``/``plate_mass_sigma_kg``: m_comp of the free run, whose error is
    common to every ``F_contact/Z`` point (as ``w^2 dm``) and passes almost one to one into m_T.
    """

    wfs_sigma: np.ndarray
    plate_sigma: np.ndarray
    displacement_relative_sigma: np.ndarray
    plate_mass_kg: float
    plate_mass_sigma_kg: float


@dataclass(frozen=True)
class ShakerFrfs:
    """The FRFs of a shaker dwell grid after plate-mass correction: ``wfs_per_z`` (F_wfs / Z),
    ``contact_per_z`` (F_contact / Z) and the paper's ``wfs_per_contact`` (F_wfs / F_contact);
    ``errors``: the parts of their errors the points share (for an identification)."""

    wfs_per_z: Frf
    contact_per_z: Frf
    wfs_per_contact: Frf
    errors: ShakerErrors


def contact_force_phasors(
    fits: Sequence[DwellFit],
    plate: PlateMass,
    *,
    shaker_force: str = "f_plate_n",
    displacement: str = "z_base_m",
) -> tuple[np.ndarray, np.ndarray]:
    """``F_contact = F_shaker + m_comp w^2 Z`` of each dwell (ascending frequency) and its standard
    uncertainty from the phasor noise of both channels and ``sigma_kg``."""
    f = np.sort([d.freq_hz for d in fits])
    m, w2 = plate.mass_kg, (2 * np.pi * f) ** 2
    (a_p, s_p), (a_z, s_z) = dwell_phasors(fits, shaker_force), dwell_phasors(fits, displacement)
    sigma = np.sqrt(s_p**2 + (m * w2 * s_z) ** 2 + (w2 * np.abs(a_z) * plate.sigma_kg) ** 2)
    return a_p + m * w2 * a_z, sigma


def shaker_frfs(
    fits: Sequence[DwellFit],
    plate: PlateMass,
    *,
    wfs: str = "fz_wfs_n",
    shaker_force: str = "f_plate_n",
    displacement: str = "z_base_m",
) -> ShakerFrfs:
    """Corrected FRFs of a dwell grid. Uncertainties propagate the phasor noise and ``sigma_kg``;
    the displacement's error enters the ratio ``F_wfs / F_contact`` through ``m_comp w^2 Z``."""
    if not fits:
        raise AnalysisInputError("no dwells given")
    ordered = sorted(fits, key=lambda d: d.freq_hz)
    f = np.array([d.freq_hz for d in ordered])
    m, w2 = plate.mass_kg, (2 * np.pi * f) ** 2
    (a_w, s_w), (a_p, s_p), (a_z, s_z) = (
        dwell_phasors(ordered, c) for c in (wfs, shaker_force, displacement)
    )
    if np.any(a_z == 0):
        raise AnalysisInputError("a dwell has no displacement at its frequency")
    a_c, s_c = contact_force_phasors(ordered, plate, shaker_force=shaker_force, displacement=displacement)
    reliable = np.array([d.settled for d in ordered])
    h_w, h_p = a_w / a_z, a_p / a_z
    sig_hw = np.sqrt(s_w**2 + np.abs(h_w) ** 2 * s_z**2) / np.abs(a_z)
    sig_hp = np.sqrt(s_p**2 + np.abs(h_p) ** 2 * s_z**2) / np.abs(a_z)
    h_c = h_p + m * w2
    sig_hc = np.hypot(sig_hp, w2 * plate.sigma_kg)
    ratio, sig_ratio = phasor_ratio(a_w, s_w, a_c, s_c)
    errors = ShakerErrors(
        s_w / np.abs(a_z), s_p / np.abs(a_z), s_z / np.abs(a_z), plate.mass_kg, plate.sigma_kg
    )
    return ShakerFrfs(
        Frf(f, h_w, sig_hw, reliable, wfs, displacement),
        Frf(f, h_c, sig_hc, reliable, "f_contact", displacement),
        Frf(f, ratio, sig_ratio, reliable, wfs, "f_contact"),
        errors,
    )


def base_acceleration_signal(
    displacement_m: np.ndarray, fs_hz: float, *, band_hz: float = 120.0
) -> np.ndarray:
    """``z''`` of a measured displacement, aligned with it: accurate to about 0.1 % up to ``band_hz``
    and rolling off above (a least-squares FIR double differentiator). The first and last
    ``latency`` samples (30 at the default length), where the differentiator lacks history or
    future, are NaN."""
    fs = as_sample_rate(fs_hz)
    z = as_signals({"displacement": displacement_m}, min_samples=61)["displacement"]
    taps, latency = double_differentiator(fs, band_hz=band_hz)
    return apply_aligned(taps, z, latency)
