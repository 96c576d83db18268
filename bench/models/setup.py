"""What stands on the bench: the bench kind, the tyre model and every parameter, as one value.

A :class:`BenchSetup` builds its mechanical network, and for a non-linear tyre the linear
equivalent network at an operating point (excitation frequency and amplitude) by harmonic balance:
the friction damping depends on the tyre deflection amplitude, which depends on the damping.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from enum import StrEnum

import numpy as np

from bench.models.benches import TyreModel, free_run, hammer_test, quarter_car, shaker_bench
from bench.models.network import MechanicalNetwork
from bench.models.parameters import Rig, Suspension, Tyre, TyreNonlinearity, WfsSensor, paper_tyre


@dataclass(frozen=True, eq=False)
class DriveDensity:
    """A broadband drive's one-sided power spectral density ``psd_m2_per_hz`` at ``freq_hz`` (evenly
    spaced by ``bin_hz``): what a non-linear element is statistically linearised for."""

    freq_hz: np.ndarray
    psd_m2_per_hz: np.ndarray
    bin_hz: float


#: Welch segment of a drive's density (s): 0.25 Hz bins, fine beside the suspension's resonances.
DENSITY_SEGMENT_S = 4.0


def drive_density(displacement_m: np.ndarray, sample_rate_hz: float) -> DriveDensity:
    """The Welch density of a drive (its mean removed; Hann segments of :data:`DENSITY_SEGMENT_S`, or
    a quarter of a shorter drive)."""
    from scipy.signal import welch

    z = np.asarray(displacement_m, dtype=float)
    segment = int(min(round(DENSITY_SEGMENT_S * sample_rate_hz), max(z.size // 4, 8)))
    f, psd = welch(z - np.mean(z), fs=sample_rate_hz, nperseg=segment)
    return DriveDensity(f, psd, float(f[1] - f[0]))


class BenchKind(StrEnum):
    SHAKER = "shaker"  # wheel centre clamped, tyre excited at the contact patch
    QUARTER_CAR = "quarter_car"  # one corner of a vehicle on a four-post bench post
    FREE_RUN = "free_run"  # shaker without a wheel (plate mass m_comp)
    HAMMER = "hammer"  # bare sensor on a rigid foundation, hammer blow


_BALANCE_TOLERANCE = 1e-5  # relative, on the deflection amplitude
#: Describing-function balances kept: more than the dry runs of every shipped shaker sequence ask
#: together, so that checking them again solves none anew.
_BALANCES_KEPT = 8192


@dataclass(frozen=True)
class BenchSetup:
    """A complete, immutable description of the simulated specimen and bench."""

    kind: BenchKind
    model: TyreModel = TyreModel.WHEEL_TREAD
    tyre: Tyre = field(default_factory=lambda: paper_tyre(2.5))
    sensor: WfsSensor = field(default_factory=WfsSensor)
    suspension: Suspension = field(default_factory=Suspension)
    rig: Rig = field(default_factory=Rig)
    nonlinearity: TyreNonlinearity | None = None

    # ------------------------------------------------------------------ presets
    @classmethod
    def paper_shaker(
        cls, pressure_bar: float = 2.5, model: TyreModel = TyreModel.WHEEL_TREAD, nonlinear: bool = True
    ) -> BenchSetup:
        """The paper's shaker test (section 2.3); the non-linear tyre as in the standard campaigns."""
        return cls(
            BenchKind.SHAKER,
            TyreModel(model),
            paper_tyre(pressure_bar),
            nonlinearity=TyreNonlinearity() if nonlinear else None,
        )

    @classmethod
    def paper_quarter_car(
        cls,
        pressure_bar: float = 2.5,
        model: TyreModel = TyreModel.WHEEL_TREAD_SIDEWALL,
        nonlinear: bool = True,
    ) -> BenchSetup:
        """One corner of the paper's vehicle on the four-post bench (section 2.4)."""
        return cls(
            BenchKind.QUARTER_CAR,
            TyreModel(model),
            paper_tyre(pressure_bar),
            rig=Rig(plate_mass_kg=15.0),
            nonlinearity=TyreNonlinearity() if nonlinear else None,
        )

    @classmethod
    def paper_free_run(cls) -> BenchSetup:
        return cls(BenchKind.FREE_RUN)

    @classmethod
    def paper_hammer(cls) -> BenchSetup:
        return cls(BenchKind.HAMMER)

    # ------------------------------------------------------------------ networks
    @property
    def has_tyre(self) -> bool:
        return self.kind in (BenchKind.SHAKER, BenchKind.QUARTER_CAR)

    def network(self, tyre: Tyre | None = None) -> MechanicalNetwork:
        """The network with the given (linear) tyre, by default the setup's nominal tyre."""
        tyre = tyre or self.tyre
        if self.kind is BenchKind.SHAKER:
            return shaker_bench(self.model, tyre, self.sensor, self.rig)
        if self.kind is BenchKind.QUARTER_CAR:
            return quarter_car(self.model, tyre, self.suspension, self.sensor, self.rig)
        if self.kind is BenchKind.FREE_RUN:
            return free_run(self.rig)
        return hammer_test(self.sensor)

    def linear_tyre(self, freq_hz: float, amplitude_m: float) -> Tyre:
        """The equivalent linear tyre for a base motion ``amplitude_m`` at ``freq_hz``.

        Solves the describing-function balance ``X = |H_X(f; d_eq(X))| * amplitude`` for X, the
        deflection amplitude of the tyre's friction element (the tyre link, or the upper sidewall
        in Model 3), by Brent's method. Below the stick deflection the equivalent damping no longer
        changes, so a balance below it is the response at the stick deflection. Linear tyres are
        returned unchanged. The balance depends on the setup and the operating point alone, and is
        kept for the next who asks (a dry run asks the same points of a sequence at every check,
        and the simulated plant those of each point it runs).
        """
        if self.nonlinearity is None or not self.has_tyre or amplitude_m <= 0:
            return self.tyre
        return _balanced_tyre(self, float(freq_hz), float(amplitude_m))

    def broadband_tyre(self, freq_hz: np.ndarray, drive_psd_m2_per_hz: np.ndarray) -> Tyre:
        """The equivalent linear tyre under a broadband Gaussian base drive of one-sided density
        ``drive_psd_m2_per_hz`` at ``freq_hz`` (a road), by statistical linearisation.

        A Coulomb force ``F_c`` whose element slides at a Gaussian velocity of rms ``sigma_v`` has
        the equivalent viscous damping ``sqrt(2 / pi) F_c / sigma_v`` (the rms-error-least linear
        damper), which the sine law ``4 F_c / (pi w X)`` gives at ``w X = 4 sigma_v / sqrt(2 pi)``;
        ``sigma_v`` depends on the damping, so the deflection is solved for by Brent's method as in
        :meth:`linear_tyre`. The stiffness, whose rise with frequency a linear system cannot follow,
        is taken at the deflection's equivalent frequency ``sigma_v / (2 pi sigma_x)`` (the sine
        with the deflection's rms and rms rate), found with the nominal tyre. Linear tyres are
        returned unchanged.
        """
        from scipy.optimize import brentq
        if self.nonlinearity is None or not self.has_tyre:
            return self.tyre
        law = self.nonlinearity
        f = np.asarray(freq_hz, dtype=float)
        weight = np.gradient(f) * np.asarray(drive_psd_m2_per_hz, dtype=float)
        lower = "z_sidewall" if self.model is TyreModel.WHEEL_TREAD_SIDEWALL else "z_base"

        def deflection_rms(tyre: Tyre) -> tuple[float, float]:
            """rms deflection (m) and deflection rate (m/s) of the friction element."""
            response = self.network(tyre).frequency_response(f, outputs=(lower, "z_rim"))
            gain2 = np.abs(response[lower] - response["z_rim"]) ** 2 * weight
            return float(np.sqrt(np.sum(gain2))), float(np.sqrt(np.sum(gain2 * (2 * np.pi * f) ** 2)))

        sigma_x, sigma_v = deflection_rms(self.tyre)
        freq_eq_hz = sigma_v / (2 * np.pi * sigma_x)
        to_sine = 4 / np.sqrt(2 * np.pi)  # sine amplitude of the Gaussian's equivalent friction damping

        def assumed_minus_solved(assumed_m: float) -> float:
            _, v = deflection_rms(law.linearised(self.tyre, freq_eq_hz, assumed_m))
            return to_sine * v / (2 * np.pi * freq_eq_hz) - assumed_m

        x_stick = law.stick_deflection_m
        if assumed_minus_solved(x_stick) <= 0:
            return law.linearised(self.tyre, freq_eq_hz, x_stick)
        # friction only slows the deflection: the frictionless rate bounds the balance from above
        x_high = 2.0 * to_sine * sigma_x + x_stick
        balance = brentq(assumed_minus_solved, x_stick, x_high, rtol=_BALANCE_TOLERANCE)
        return law.linearised(self.tyre, freq_eq_hz, balance)

    @property
    def nonlinear(self) -> bool:
        """Whether the setup's response depends on its level: a non-linear tyre, or a quarter car's
        non-linear damper."""
        damper = self.kind is BenchKind.QUARTER_CAR and self.suspension.damper is not None
        return self.has_tyre and (self.nonlinearity is not None or damper)

    def operating_network(
        self, freq_hz: float, amplitude_m: float, density: DriveDensity | None = None
    ) -> MechanicalNetwork:
        """The linear equivalent network at an operating point: the tyre linearised there, then a
        quarter car's damper, for the sine or (``density``) the broadband drive (the nominal network
        when both are linear)."""
        tyre = self.linear_tyre(freq_hz, amplitude_m)
        return self.linear_damper(tyre, freq_hz, amplitude_m, density).network(tyre)

    def linear_damper(
        self, tyre: Tyre, freq_hz: float, amplitude_m: float, density: DriveDensity | None = None
    ) -> BenchSetup:
        """This setup with its quarter car's damper replaced by the equivalent viscous one (with the
        linear ``tyre``), the balance of the stroke's velocity solved by Brent's method
        (:class:`~bench.models.parameters.DamperNonlinearity`): for a base sine ``amplitude_m`` at
        ``freq_hz``, its amplitude ``V = w |z_body - z_hub| amplitude``; for a broadband base drive
        of ``density``, its rms ``sigma^2 = sum w^2 |z_body - z_hub|^2 G df``. Unchanged without a
        non-linear damper."""
        from scipy.optimize import brentq

        suspension = self.suspension
        if self.kind is not BenchKind.QUARTER_CAR or suspension.damper is None or amplitude_m <= 0:
            return self
        gaussian = density is not None
        if density is not None:
            f = np.maximum(density.freq_hz, 1e-3)
            weight = density.psd_m2_per_hz * density.bin_hz
        else:
            f, weight = np.array([max(freq_hz, 1e-3)]), np.array([amplitude_m**2])

        def velocity_m_s(assumed_m_s: float) -> float:
            linear = replace(self, suspension=suspension.linearised(assumed_m_s, gaussian=gaussian))
            response = linear.network(tyre).frequency_response(f, outputs=("z_body", "z_hub"))
            stroke = (2 * np.pi * f) ** 2 * np.abs(response["z_body"] - response["z_hub"]) ** 2
            return float(np.sqrt(np.sum(stroke * weight)))

        knee = suspension.damper.knee_velocity_m_s
        low = 1e-3 * knee if gaussian else knee  # a Gaussian velocity passes the knee at any rms
        if velocity_m_s(low) <= low:
            return replace(self, suspension=suspension.linearised(low, gaussian=gaussian))
        # the least damping (the high-speed branch) lets the stroke move fastest: an upper bound
        high = 2.0 * velocity_m_s(1e6 * knee)
        balance = brentq(lambda v: velocity_m_s(v) - v, low, max(high, 2 * low), rtol=_BALANCE_TOLERANCE)
        return replace(self, suspension=suspension.linearised(balance, gaussian=gaussian))

    def with_tyre(self, tyre: Tyre) -> BenchSetup:
        return replace(self, tyre=tyre)


@functools.lru_cache(maxsize=_BALANCES_KEPT)
def _balanced_tyre(setup: BenchSetup, freq_hz: float, amplitude_m: float) -> Tyre:
    """:meth:`BenchSetup.linear_tyre` of a setup with a non-linear tyre."""
    from scipy.optimize import brentq

    law = setup.nonlinearity
    assert law is not None
    lower = "z_sidewall" if setup.model is TyreModel.WHEEL_TREAD_SIDEWALL else "z_base"

    def deflection_m(assumed_m: float) -> float:
        network = setup.network(law.linearised(setup.tyre, freq_hz, assumed_m))
        response = network.frequency_response(freq_hz, outputs=(lower, "z_rim"))
        return float(np.abs(response[lower][0] - response["z_rim"][0])) * amplitude_m

    x_stick = law.stick_deflection_m
    at_stick = deflection_m(x_stick)
    if at_stick <= x_stick:
        return law.linearised(setup.tyre, freq_hz, at_stick)
    # The deflection with the least friction damping bounds the balance from above.
    x_high = 2.0 * max(at_stick, deflection_m(1e3 * max(amplitude_m, x_stick)))
    balance = brentq(lambda x: deflection_m(x) - x, x_stick, x_high, rtol=_BALANCE_TOLERANCE)
    return law.linearised(setup.tyre, freq_hz, balance)
