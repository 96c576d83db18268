"""The bench's actuator: a servo-hydraulic position loop driving the plate and the specimen.

A real servo-hydraulic shaker does not follow its displacement command exactly. The oil in the
cylinder is a spring, the piston and everything on it a mass, the specimen pushes back with its own
dynamic stiffness, and the servo valve can deliver only so much flow. :class:`ServoActuator` models
these, linear per operating point; :class:`IdealServo` is the stiff position servo of earlier
versions, kept for analyses that need a base motion independent of the load.

Both answer the same three questions for :class:`~simulators.plant.simulator.PlantSimulator`:
``drive(network)`` (the actuator coupled to the specimen network, as one linear system from the
displacement command), ``gain(freq_hz, load_n_per_m, flow_factor)`` (base displacement per unit
command, closed form) and ``flow_factor(freq_hz, command_amplitude_m, load_n_per_m)`` (the valve's
equivalent gain at an operating point).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from bench.models.linear_system import LinearSystem

#: Outputs every actuator gives before the network's: the base (plate) motion.
BASE_OUTPUTS = ("z_base", "v_base", "a_base")
#: The network output the actuator pushes against: the plate force (plate inertia + contact force).
LOAD_OUTPUT = "f_plate"


def saturation_gain(overdrive: float) -> float:
    """Describing function of a unit-slope saturation driven ``overdrive`` times past its limit.

    For a sine of amplitude E into a saturation of slope 1 and limit L, with ``overdrive = E / L``,
    the fundamental of the output over E is 1 when E <= L, else ``(2/pi)(asin r + r sqrt(1 - r^2))``
    with ``r = L / E`` (it tends to ``4 / (pi overdrive)``, the square wave's, for a large overdrive).
    """
    if overdrive <= 1.0:
        return 1.0
    r = 1.0 / overdrive
    return (2.0 / math.pi) * (math.asin(r) + r * math.sqrt(1.0 - r * r))


@dataclass(frozen=True)
class ServoActuator:
    """Servo-hydraulic actuator under position control, pushing the plate and the specimen.

    Equations (z the piston and plate displacement, F = A p the hydraulic force, q the valve flow
    per piston area, i.e. the velocity the flow alone would give):

    - position loop and servo valve: ``tau q' = -q + N K_v (z_command - z)``; ``K_v`` (1/s) is the
      loop gain (controller gain times valve flow gain over piston area), ``tau`` the valve's
      first-order lag, ``N`` the flow factor below;
    - oil column: ``F' = k_h (q - v) - lambda F``; ``k_h = 4 beta A^2 / V`` is the oil-column
      stiffness, ``lambda`` the rate at which the cross-port bleed relieves the load pressure;
    - piston: ``m_a a = F - F_plate``, where ``F_plate`` (plate inertia plus the specimen's
      contact force) is what the load cell under the plate reads.

    With the load's dynamic stiffness ``K(s) = F_plate / Z`` (from the network) and
    ``K_tot = m_a s^2 + K``, the base displacement per unit command is

        G(s) = N K_v / ((tau s + 1)(s + K_tot(s) (s + lambda) / k_h) + N K_v),

    so what is mounted changes the response: the plate alone (free run) is a mass, the wheel adds
    its tyre spring and tread mass (whose stiffness changes sign through the tread resonance), the
    quarter car its wheel and body modes. The loop has one integrator (the valve's flow), so the
    response is 1 at 0 Hz except for what the bleed lets a static spring load push away.

    Flow limit: the valve opens at most as far as its rated flow, i.e. the command
    ``K_v (z_command - z)`` saturates at ``flow_limited_velocity_m_s``. A sine error of amplitude E
    then sees the equivalent gain ``N = saturation_gain(K_v E / v_max)`` (a describing function,
    as the tyre's friction is linearised in ``bench.models.parameters.TyreNonlinearity``); E depends
    on N, so N solves ``N = saturation_gain(K_v |1 - G(N)| A / v_max)`` (Brent) per operating point.

    Parameters of a 25 kN, +-50 mm shaker cylinder (piston area 20 cm^2 at 210 bar supply):
    ``k_h`` 40 MN/m from ``beta`` = 1.4 GPa (mineral oil with some entrained air) and 0.56 l of
    oil under compression (0.2 l in both chambers, the rest in manifold and hoses); piston, rod
    and load-cell adaptor 8 kg (with the 12 kg plate the bare bench's oil-column resonance is
    225 Hz); a two-stage valve with a 200 Hz first-order bandwidth; a cross-port bleed relieving
    the load pressure at 800 1/s, which damps the loop's modes at 100-300 Hz to 17-20 % (Model 3's
    sidewall modes to 8-13 %); a loop gain of 500 1/s, which leaves a gain margin of 1.6 on the
    worst specimen (Model 2 on either bench: unstable from 790 1/s; ``benchmarks/model_figures.py``
    prints these); rated flow for 1.2 m/s
    (144 l/min at 20 cm^2). The result, uncorrected, with the wheel at 2.5 bar: -1.5 % at 1 Hz
    (the bleed under the tyre spring), within 1.5 % to 30 Hz, then +2.3 / +4.7 / +7.7 / +11.6 % at
    40 / 50 / 60 / 70 Hz; the bare plate +7.2 % and the quarter car +16 % at 70 Hz
    (docs/physics.md). The run engine's amplitude control corrects these.
    """

    moving_mass_kg: float = 8.0
    oil_stiffness_n_per_m: float = 40e6
    bleed_rate_per_s: float = 800.0
    loop_gain_per_s: float = 500.0
    valve_bandwidth_hz: float = 200.0
    flow_limited_velocity_m_s: float = 1.2

    def __post_init__(self) -> None:
        for name in (
            "moving_mass_kg",
            "oil_stiffness_n_per_m",
            "loop_gain_per_s",
            "valve_bandwidth_hz",
            "flow_limited_velocity_m_s",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"actuator {name} must be positive, got {getattr(self, name)}")
        if self.bleed_rate_per_s < 0:
            raise ValueError(f"actuator bleed_rate_per_s must not be negative, got {self.bleed_rate_per_s}")

    @property
    def valve_time_constant_s(self) -> float:
        return 1.0 / (2 * math.pi * self.valve_bandwidth_hz)

    def gain(self, freq_hz: float, load_n_per_m: complex = 0j, flow_factor: float = 1.0) -> complex:
        """Base displacement per unit command at ``freq_hz`` against the load ``K = F_plate / Z``."""
        s = 2j * math.pi * freq_hz
        k_total = self.moving_mass_kg * s * s + load_n_per_m
        loop = flow_factor * self.loop_gain_per_s
        plant = (self.valve_time_constant_s * s + 1) * (
            s + k_total * (s + self.bleed_rate_per_s) / self.oil_stiffness_n_per_m
        )
        return complex(loop / (plant + loop))

    def flow_factor(self, freq_hz: float, command_amplitude_m: float, load_n_per_m: complex) -> float:
        """The valve's equivalent gain N (1: not flow limited) for a sine command at ``freq_hz``."""

        def overdrive(factor: float) -> float:
            error_m = abs(1 - self.gain(freq_hz, load_n_per_m, factor)) * command_amplitude_m
            return self.loop_gain_per_s * error_m / self.flow_limited_velocity_m_s

        if overdrive(1.0) <= 1.0:
            return 1.0
        # N = 1 gives too much (saturated), N -> 0 too little: the balance lies between.
        return float(brentq(lambda n: saturation_gain(overdrive(n)) - n, 1e-9, 1.0, xtol=1e-12))

    def drive(self, network: LinearSystem, flow_factor: float = 1.0) -> LinearSystem:
        """The actuator coupled to a network (inputs ``z_base, v_base, a_base``; output ``f_plate``).

        States ``[z, v, c, q]`` then the network's, with ``c = F / k_h`` the oil column's compression
        (in metres, like z: the state vector stays well scaled for the modal stepping); input
        ``z_command``; outputs the base motion, then the network's outputs. The piston's
        acceleration is solved from ``m_a a = k_h c - F_plate`` where ``F_plate`` itself holds ``a``
        (plate and tread inertia): no algebraic loop remains.
        """
        if network.inputs[:3] != BASE_OUTPUTS or LOAD_OUTPUT not in network.outputs:
            raise ValueError(f"the actuator drives a network with inputs {BASE_OUTPUTS} and output f_plate")
        n = len(network.states)
        size = 4 + n
        p = network.outputs.index(LOAD_OUTPUT)
        load_x, load_u = network.C[p], network.D[p, :3]
        k_h = self.oil_stiffness_n_per_m
        accel = np.zeros(size)  # a = (k_h c - F_plate(z, v, x_network)) / (m_a + inertia in F_plate)
        accel[0], accel[1], accel[2] = -load_u[0], -load_u[1], k_h
        accel[4:] = -load_x
        accel /= self.moving_mass_kg + load_u[2]
        base = np.zeros((3, size))  # z, v, a as rows over the whole state
        base[0, 0], base[1, 1], base[2] = 1.0, 1.0, accel
        tau = self.valve_time_constant_s
        loop = flow_factor * self.loop_gain_per_s
        A = np.zeros((size, size))
        A[0, 1] = 1.0
        A[1] = accel
        A[2, 3], A[2, 1], A[2, 2] = 1.0, -1.0, -self.bleed_rate_per_s
        A[3, 3], A[3, 0] = -1.0 / tau, -loop / tau
        A[4:] = network.B[:, :3] @ base
        A[4:, 4:] += network.A
        B = np.zeros((size, 1))
        B[3, 0] = loop / tau
        C = np.vstack([base, network.C @ np.hstack([np.zeros((n, 4)), np.eye(n)]) + network.D[:, :3] @ base])
        return LinearSystem(
            A,
            B,
            C,
            np.zeros((C.shape[0], 1)),
            inputs=("z_command",),
            outputs=BASE_OUTPUTS + network.outputs,
            states=("actuator_z", "actuator_v", "oil_compression", "valve_flow", *network.states),
        )


@dataclass(frozen=True)
class IdealServo:
    """A stiff position servo: third-order Butterworth low-pass from command to motion, no load effect.

    Third order because a servo valve's flow lags its current: acceleration follows the command
    only through the dynamics, with no direct feedthrough. Neither the load nor a flow limit
    changes its response (0.1 % amplitude error at 70 Hz with the default 200 Hz bandwidth).
    """

    bandwidth_hz: float = 200.0

    def system(self) -> LinearSystem:
        w = 2 * math.pi * self.bandwidth_hz
        jerk_row = np.array([[-(w**3), -2 * w**2, -2 * w]])
        return LinearSystem(
            A=np.vstack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], jerk_row]),
            B=np.array([[0.0], [0.0], [w**3]]),
            C=np.eye(3),
            D=np.zeros((3, 1)),
            inputs=("z_command",),
            outputs=BASE_OUTPUTS,
            states=("actuator_z", "actuator_v", "actuator_a"),
        )

    def gain(self, freq_hz: float, load_n_per_m: complex = 0j, flow_factor: float = 1.0) -> complex:
        """Base displacement per unit command at ``freq_hz`` (whatever the load)."""
        s = 1j * freq_hz / self.bandwidth_hz
        return 1.0 / (s**3 + 2 * s**2 + 2 * s + 1)

    def flow_factor(self, freq_hz: float, command_amplitude_m: float, load_n_per_m: complex) -> float:
        """Never flow limited."""
        return 1.0

    def drive(self, network: LinearSystem, flow_factor: float = 1.0) -> LinearSystem:
        """The servo in series with the network: the network's base motion is the servo's output."""
        return self.system().then(network)


Actuator = ServoActuator | IdealServo
