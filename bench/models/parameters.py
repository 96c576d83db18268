"""Physical parameters of the wheel force sensor, the tyre/wheel, the suspension and the rigs.

Every value carries its unit in its name. The paper's values (shared/seed, sections 2.2 and 3) are
the defaults and the named presets; values the paper does not give (sidewall of Model 3, quarter-car
suspension and body, plate masses, the non-linearity law) are stated where they are set, chosen so
that the features the paper reports appear where it reports them (wheel eigenfrequency about 15 Hz,
mass split above/below the sensor about 50 %).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

#: Tyre vertical stiffness identified on the shaker bench per inflation pressure (paper, 3.1).
PAPER_TYRE_STIFFNESS_N_PER_M: dict[float, float] = {1.5: 250e3, 2.5: 390e3, 3.5: 420e3}


@dataclass(frozen=True)
class WfsSensor:
    """The wheel force sensor as a stiff spring/damper, its stiffness from the hammer test.

    The paper's sensor weighs 3.82 kg and its hammer-test eigenfrequency is "even over 2 kHz";
    2.2 kHz and a damping ratio of 2 % (a bolted steel structure) are the defaults.
    """

    mass_kg: float = 3.82
    eigenfrequency_hz: float = 2200.0
    damping_ratio: float = 0.02

    def __post_init__(self) -> None:
        if self.mass_kg <= 0 or self.eigenfrequency_hz <= 0 or self.damping_ratio < 0:
            raise ValueError(f"invalid sensor parameters: {self}")

    @property
    def stiffness_n_per_m(self) -> float:
        """k = m (2 pi f)^2 of the sensor mass on its own elasticity (hammer test on a rigid base)."""
        return self.mass_kg * (2 * math.pi * self.eigenfrequency_hz) ** 2

    @property
    def damping_ns_per_m(self) -> float:
        """d = 2 zeta sqrt(k m)."""
        return 2 * self.damping_ratio * math.sqrt(self.stiffness_n_per_m * self.mass_kg)


@dataclass(frozen=True)
class Tyre:
    """Linear tyre/wheel parameters shared by Models 1-3 (paper, 3.1).

    ``wheel_mass_kg`` is all the mass between the sensing element and the road (tyre, rim, adaption
    and the sensor's outer part): 29 kg in the paper. Model 2 splits off ``tread_mass_kg`` (6 kg),
    which moves with the contact patch; Model 3 also splits off ``sidewall_mass_kg`` between a lower
    and an upper sidewall spring, in parallel with the air spring ``stiffness_n_per_m`` (k_air, equal
    to the Model 1/2 tyre stiffness as in the paper). ``damping_ns_per_m`` is the tyre damper of
    Models 1/2 and the upper sidewall damper of Model 3 (80 Ns/m in the paper).

    The sidewall values are not in the paper ("cannot be easily estimated ... low sensitivity"):
    a 1 kg sidewall, stiff towards the tread (1 MN/m: local mode far above 70 Hz) and soft towards
    the rim (30 kN/m), so that Model 3 follows Model 2 on the shaker bench as the paper reports.
    """

    stiffness_n_per_m: float
    damping_ns_per_m: float = 80.0
    wheel_mass_kg: float = 29.0
    tread_mass_kg: float = 6.0
    sidewall_mass_kg: float = 1.0
    sidewall_lower_stiffness_n_per_m: float = 1.0e6
    sidewall_upper_stiffness_n_per_m: float = 30e3

    def __post_init__(self) -> None:
        for name in ("stiffness_n_per_m", "wheel_mass_kg"):
            if not getattr(self, name) > 0:
                raise ValueError(f"tyre {name} must be positive, got {getattr(self, name)}")
        if self.damping_ns_per_m < 0 or self.tread_mass_kg < 0 or self.sidewall_mass_kg < 0:
            raise ValueError(f"tyre damping and masses must not be negative: {self}")
        if self.tread_mass_kg + self.sidewall_mass_kg >= self.wheel_mass_kg:
            raise ValueError("tread and sidewall masses must leave a positive rim mass")


def paper_tyre(pressure_bar: float) -> Tyre:
    """The paper's tyre at 1.5, 2.5 or 3.5 bar."""
    try:
        return Tyre(stiffness_n_per_m=PAPER_TYRE_STIFFNESS_N_PER_M[pressure_bar])
    except KeyError:
        known = sorted(PAPER_TYRE_STIFFNESS_N_PER_M)
        raise ValueError(f"no paper tyre at {pressure_bar} bar; known pressures: {known}") from None


#: Tyre pressures (bar) a simulated tyre may be inflated to: the paper's range with half a bar each side.
TYRE_PRESSURE_RANGE_BAR = (1.0, 4.0)


def tyre_at_pressure(pressure_bar: float) -> Tyre:
    """The paper's tyre inflated to any pressure in :data:`TYRE_PRESSURE_RANGE_BAR`.

    The stiffness is interpolated piecewise linearly between the paper's three points (250 / 390 /
    420 kN/m at 1.5 / 2.5 / 3.5 bar) and extended beyond them along the end segments (180 kN/m at
    1 bar, 435 kN/m at 4 bar): the measured relation is all there is, and its flattening above
    2.5 bar is kept. At the paper's pressures it is exactly :func:`paper_tyre`. ValueError outside
    the range.
    """
    low, high = TYRE_PRESSURE_RANGE_BAR
    if not low <= pressure_bar <= high:
        raise ValueError(f"tyre pressure {pressure_bar} bar is outside {low}-{high} bar")
    points = sorted(PAPER_TYRE_STIFFNESS_N_PER_M.items())
    segment = 0
    while segment < len(points) - 2 and pressure_bar > points[segment + 1][0]:
        segment += 1
    (p0, k0), (p1, k1) = points[segment], points[segment + 1]
    return Tyre(stiffness_n_per_m=k0 + (k1 - k0) * (pressure_bar - p0) / (p1 - p0))


@dataclass(frozen=True)
class TyreNonlinearity:
    """Rubber behaviour as an equivalent linearisation (describing function) per operating point.

    - Dynamic stiffness rises with frequency, ``k(f) = k (1 + rate * log10(f / f_ref))`` for
      ``f >= f_min`` (constant below), the logarithmic law of filled rubber.
    - Rubber friction: a Coulomb force ``friction_force_n`` in parallel with the damper. Its
      describing function for a tyre deflection of amplitude X at circular frequency w is the
      equivalent viscous damping ``4 F_c / (pi w X)``: damping falls as amplitude grows, so the
      1 / 2 / 5 mm curves differ near the tread resonance. Below ``stick_deflection_m`` the friction
      contact sticks (micro-slip), which bounds the equivalent damping of tiny deflections.

    The plant finds X by harmonic balance, so a sine dwell's steady state is exact for this law.
    """

    stiffness_rise_per_decade: float = 0.03
    reference_frequency_hz: float = 10.0
    min_frequency_hz: float = 0.5
    friction_force_n: float = 4.0
    stick_deflection_m: float = 1e-4

    def stiffness_factor(self, freq_hz: float) -> float:
        """k(f) / k."""
        f = max(freq_hz, self.min_frequency_hz)
        return 1.0 + self.stiffness_rise_per_decade * math.log10(f / self.reference_frequency_hz)

    def friction_damping_ns_per_m(self, freq_hz: float, deflection_amplitude_m: float) -> float:
        """Equivalent viscous damping of the friction element."""
        w = 2 * math.pi * max(freq_hz, self.min_frequency_hz)
        x = max(deflection_amplitude_m, self.stick_deflection_m)
        return 4 * self.friction_force_n / (math.pi * w * x)

    def linearised(self, tyre: Tyre, freq_hz: float, deflection_amplitude_m: float) -> Tyre:
        """The linear tyre equivalent at one operating point (frequency, tyre deflection amplitude)."""
        return replace(
            tyre,
            stiffness_n_per_m=tyre.stiffness_n_per_m * self.stiffness_factor(freq_hz),
            damping_ns_per_m=tyre.damping_ns_per_m
            + self.friction_damping_ns_per_m(freq_hz, deflection_amplitude_m),
        )


@dataclass(frozen=True)
class Suspension:
    """Quarter-car suspension above the sensor (paper, 3.2; values not given there).

    ``unsprung_mass_above_kg`` is the remaining unsprung mass (hub carrier, brake, half the links)
    above the sensing element: with the 29 kg wheel below it, the mass split above/below is 46 %
    (the paper observes about 50 %) and the wheel eigenfrequency about 14 Hz (about 15 Hz in the
    paper). A firm spring and a middle-firm damper as on the paper's test vehicle.
    """

    unsprung_mass_above_kg: float = 25.0
    stiffness_n_per_m: float = 40e3
    damping_ns_per_m: float = 3000.0
    body_mass_kg: float = 380.0
    damper: DamperNonlinearity | None = None

    def __post_init__(self) -> None:
        if min(self.unsprung_mass_above_kg, self.stiffness_n_per_m, self.body_mass_kg) <= 0:
            raise ValueError(f"suspension masses and stiffness must be positive: {self}")
        if self.damping_ns_per_m < 0:
            raise ValueError("suspension damping must not be negative")

    def linearised(self, stroke_velocity_m_s: float, *, gaussian: bool = False) -> Suspension:
        """This suspension with its damper replaced by the equivalent viscous one at a sine stroke
        velocity amplitude ``stroke_velocity_m_s`` or (``gaussian``) a Gaussian stroke velocity of
        that rms (unchanged for a linear damper)."""
        if self.damper is None:
            return self
        law, low = self.damper, self.damping_ns_per_m
        if gaussian:
            c = law.gaussian_damping_ns_per_m(low, stroke_velocity_m_s)
        else:
            c = law.equivalent_damping_ns_per_m(low, stroke_velocity_m_s)
        return replace(self, damping_ns_per_m=c, damper=None)


@dataclass(frozen=True)
class DamperNonlinearity:
    """A digressive shock absorber: ``damping_ns_per_m`` of the suspension up to the blow-off valve's
    ``knee_velocity_m_s``, ``high_speed_ratio`` of it beyond (a passenger car's damper has a steep
    low-speed branch for body control and opens to a flatter one for wheel control).

    The force ``c2 v + (c1 - c2) sat(v, v_k)`` is linearised for a sine by its describing function:
    the saturation's gain is ``(2 / pi)(asin r + r sqrt(1 - r^2))``, ``r = v_k / V``, at velocity
    amplitude ``V > v_k``; for a broadband (Gaussian) stroke velocity of rms ``sigma`` statistically:
    the gain is the expected slope, the probability ``erf(v_k / (sqrt 2 sigma))`` of the low-speed
    branch. The knee, 0.3 m/s, lies above the strokes of the four-post bench's 2 mm sweeps (at most
    0.27 m/s, at the wheel hop) and below a class C road's peaks: sweeps see a linear damper, a
    road's large strokes far less damping than a low-level identification drive's small ones.
    """

    knee_velocity_m_s: float = 0.3
    high_speed_ratio: float = 1 / 3

    def __post_init__(self) -> None:
        if not self.knee_velocity_m_s > 0 or not 0 < self.high_speed_ratio <= 1:
            raise ValueError(f"a damper's knee velocity must be positive and its ratio in (0, 1]: {self}")

    def equivalent_damping_ns_per_m(self, low_speed_ns_per_m: float, velocity_amplitude_m_s: float) -> float:
        """The equivalent viscous damping at a sine velocity amplitude (the low-speed damping at or
        below the knee)."""
        high = self.high_speed_ratio * low_speed_ns_per_m
        if velocity_amplitude_m_s <= self.knee_velocity_m_s:
            return low_speed_ns_per_m
        r = self.knee_velocity_m_s / velocity_amplitude_m_s
        gain = (2 / math.pi) * (math.asin(r) + r * math.sqrt(1 - r * r))
        return high + (low_speed_ns_per_m - high) * gain

    def gaussian_damping_ns_per_m(self, low_speed_ns_per_m: float, velocity_rms_m_s: float) -> float:
        """The statistically linearised damping at a Gaussian velocity of rms ``velocity_rms_m_s``."""
        high = self.high_speed_ratio * low_speed_ns_per_m
        if velocity_rms_m_s <= 0:
            return low_speed_ns_per_m
        below = math.erf(self.knee_velocity_m_s / (math.sqrt(2) * velocity_rms_m_s))
        return high + (low_speed_ns_per_m - high) * below


@dataclass(frozen=True)
class Rig:
    """The bench under the specimen: its plate mass above the load cell (m_comp to identify)."""

    plate_mass_kg: float = 12.0

    def __post_init__(self) -> None:
        if self.plate_mass_kg < 0:
            raise ValueError("plate mass must not be negative")
