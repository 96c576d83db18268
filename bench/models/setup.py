"""What stands on the bench: the bench kind, the tyre model and every parameter, as one value.

A :class:`BenchSetup` builds its mechanical network, and for a non-linear tyre the linear
equivalent network at an operating point (excitation frequency and amplitude) by harmonic balance:
the friction damping depends on the tyre deflection amplitude, which depends on the damping.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import StrEnum

import numpy as np

from bench.models.benches import TyreModel, free_run, hammer_test, quarter_car, shaker_bench
from bench.models.network import MechanicalNetwork
from bench.models.parameters import Rig, Suspension, Tyre, TyreNonlinearity, WfsSensor, paper_tyre


class BenchKind(StrEnum):
    SHAKER = "shaker"  # wheel centre clamped, tyre excited at the contact patch
    QUARTER_CAR = "quarter_car"  # one corner of a vehicle on a four-post bench post
    FREE_RUN = "free_run"  # shaker without a wheel (plate mass m_comp)
    HAMMER = "hammer"  # bare sensor on a rigid foundation, hammer blow


_BALANCE_TOLERANCE = 1e-6
_BALANCE_MAX_ITERATIONS = 200


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

        Solves the describing-function fixed point ``X = |H_X(f; d_eq(X))| * amplitude``, where X is
        the deflection amplitude of the tyre's friction element (the tyre link, or the upper
        sidewall in Model 3). Linear tyres are returned unchanged.
        """
        if self.nonlinearity is None or not self.has_tyre:
            return self.tyre
        law = self.nonlinearity
        deflection = max(amplitude_m, law.stick_deflection_m)
        for _ in range(_BALANCE_MAX_ITERATIONS):
            tyre = law.linearised(self.tyre, freq_hz, deflection)
            response = self.network(tyre).frequency_response(freq_hz)
            lower = "z_sidewall" if self.model is TyreModel.WHEEL_TREAD_SIDEWALL else "z_base"
            new = float(np.abs(response[lower][0] - response["z_rim"][0])) * amplitude_m
            if abs(new - deflection) <= _BALANCE_TOLERANCE * max(deflection, 1e-12):
                return law.linearised(self.tyre, freq_hz, new)
            deflection = 0.5 * (deflection + new)  # damped iteration: robust near resonance
        raise RuntimeError(f"harmonic balance did not converge at {freq_hz} Hz, {amplitude_m} m")

    def operating_network(self, freq_hz: float, amplitude_m: float) -> MechanicalNetwork:
        """The linear equivalent network at an operating point (the nominal one for linear tyres)."""
        return self.network(self.linear_tyre(freq_hz, amplitude_m))

    def with_tyre(self, tyre: Tyre) -> BenchSetup:
        return replace(self, tyre=tyre)
