"""The servo-hydraulic actuator: its closed-form response, the load it feels, its flow limit, stability."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from bench.models.benches import TyreModel
from bench.models.parameters import paper_tyre
from bench.models.setup import BenchKind, BenchSetup
from simulators.plant import IdealServo, PlantSimulator, SensorRealism, ServoActuator, SineDwell
from simulators.plant.actuator import saturation_gain

ACTUATOR = ServoActuator()


def fundamental(signal: np.ndarray, freq_hz: float, rate_hz: float, cycles: int) -> complex:
    """Complex amplitude at ``freq_hz`` over the last ``cycles`` whole cycles."""
    n = round(cycles * rate_hz / freq_hz)
    t = np.arange(signal.size)[-n:] / rate_hz
    return 2 * np.mean(signal[-n:] * np.exp(-2j * np.pi * freq_hz * t))


def load_n_per_m(setup: BenchSetup, freq_hz: float) -> complex:
    """Plate force per metre of base displacement: what the actuator pushes."""
    return complex(setup.network().frequency_response(freq_hz, outputs=("f_plate",))["f_plate"][0])


def measured_gain(setup: BenchSetup, freq_hz: float, amplitude_m: float) -> complex:
    plant = PlantSimulator(setup, realism=SensorRealism.ideal())
    cycles = round(freq_hz)
    rec = plant.simulate(SineDwell(freq_hz, amplitude_m, hold_s=1.5 + cycles / freq_hz, taper_out_s=0.0))
    return fundamental(rec["z_base_m"], freq_hz, 1000.0, cycles) / (-1j * amplitude_m)  # sin -> -j


@pytest.mark.parametrize(
    ("setup", "freq_hz"),
    [
        (BenchSetup.paper_free_run(), 60.0),
        (BenchSetup.paper_shaker(2.5, nonlinear=False), 40.6),
        (BenchSetup.paper_shaker(1.5, nonlinear=False), 70.0),
        (BenchSetup.paper_quarter_car(2.5, nonlinear=False), 14.0),
    ],
    ids=["bare plate", "wheel at tread resonance", "wheel 1.5 bar", "quarter car wheel mode"],
)
def test_time_domain_actuator_follows_its_closed_form_transfer_function(setup, freq_hz):
    """G = K_v / ((tau s + 1)(s + (m_a s^2 + K(s))(s + lambda) / k_h) + K_v), K the network's load."""
    expected = ACTUATOR.gain(freq_hz, load_n_per_m(setup, freq_hz))
    assert measured_gain(setup, freq_hz, 0.001) == pytest.approx(expected, rel=2e-4)


def test_closed_form_limits():
    """At 0 Hz only the bleed lets a spring load push the piston back: G = 1 / (1 + lambda k / (k_h K_v)).
    Against a pure mass the loop is exact at 0 Hz, and far above the bandwidth the response falls as
    the product of its lags (third order with the valve)."""
    k = 390e3
    a = ACTUATOR
    static = 1 / (1 + a.bleed_rate_per_s * k / (a.oil_stiffness_n_per_m * a.loop_gain_per_s))
    assert ACTUATOR.gain(1e-9, k) == pytest.approx(static, rel=1e-9)
    assert static == pytest.approx(0.9846, abs=1e-4)
    assert ACTUATOR.gain(1e-9, -20.0 * (2e-9 * math.pi) ** 2) == pytest.approx(1.0, abs=1e-8)
    f = 20e3
    w = 2 * math.pi * f
    mass_kg = ACTUATOR.moving_mass_kg + 12.0
    tail = ACTUATOR.loop_gain_per_s * ACTUATOR.oil_stiffness_n_per_m / (
        ACTUATOR.valve_time_constant_s * mass_kg * w**4
    )
    assert abs(ACTUATOR.gain(f, -12.0 * w**2)) == pytest.approx(tail, rel=0.02)


def test_uncorrected_errors_of_several_percent_at_40_to_70_hz():
    plant = PlantSimulator(BenchSetup.paper_shaker(2.5))
    errors = {f: abs(plant.base_gain(f, 0.002)) - 1 for f in (10.0, 40.0, 50.0, 60.0, 70.0)}
    assert abs(errors[10.0]) < 0.02
    assert 0.02 < errors[40.0] < errors[50.0] < errors[60.0] < errors[70.0] < 0.15
    ideal = PlantSimulator(BenchSetup.paper_shaker(2.5), actuator=IdealServo())
    assert abs(abs(ideal.base_gain(70.0, 0.002)) - 1) < 1.5e-3  # the old behaviour, on request


def test_the_load_changes_the_response_except_where_the_tread_cancels_the_tyre_spring():
    """The wheel adds k + j w d - m_T w^2 to the bare plate's load: at the tread resonance
    sqrt(k / m_T) stiffness and inertia cancel and only the tyre damper is left, so the actuator moves
    as with the bare plate; below it the tyre spring, above it the tread's inertia change the response."""
    bare = BenchSetup.paper_free_run()
    wheel = BenchSetup.paper_shaker(2.5, nonlinear=False)
    tread_hz = math.sqrt(wheel.tyre.stiffness_n_per_m / wheel.tyre.tread_mass_kg) / (2 * math.pi)
    difference = {}
    for f in (5.0, tread_hz, 70.0):
        g_bare, g_wheel = (ACTUATOR.gain(f, load_n_per_m(s, f)) for s in (bare, wheel))
        difference[f] = abs(g_wheel / g_bare) - 1
    assert abs(difference[tread_hz]) < 2e-3
    assert difference[5.0] < -0.01  # the tyre spring pushes back through the bleed
    assert difference[70.0] > 0.03  # the tread's inertia lowers the load: resonance peaking grows
    assert measured_gain(bare, 70.0, 0.001) != pytest.approx(measured_gain(wheel, 70.0, 0.001), rel=0.02)


def test_every_specimen_leaves_the_loop_stable_and_the_oil_column_damped():
    setups = [BenchSetup.paper_free_run()] + [
        BenchSetup(kind, model, paper_tyre(p))
        for kind in (BenchKind.SHAKER, BenchKind.QUARTER_CAR)
        for model in TyreModel
        for p in (1.5, 2.5, 3.5)
    ]
    for setup in setups:
        network = setup.network()
        outputs = [o for o in ("z_base", "f_plate", "f_wfs", "f_contact") if o in network.output_names]
        poles = np.linalg.eigvals(ACTUATOR.drive(network.state_space(outputs=outputs)).A)
        assert poles.real.max() < 0, setup
        hydraulic = poles[(np.abs(poles) > 2 * np.pi * 100) & (np.abs(poles) < 2 * np.pi * 300)]
        assert np.all(-hydraulic.real / np.abs(hydraulic) > 0.07), setup  # Model 3 sidewall: 8 %


def test_saturation_describing_function():
    assert saturation_gain(0.5) == 1.0 and saturation_gain(1.0) == 1.0
    assert saturation_gain(2.0) == pytest.approx((2 / math.pi) * (math.pi / 6 + 0.5 * math.sqrt(0.75)))
    assert saturation_gain(1e4) == pytest.approx(4 / (math.pi * 1e4), rel=1e-6)


def test_flow_limit_balance_and_the_amplitude_drop():
    load = load_n_per_m(BenchSetup.paper_free_run(), 70.0)
    assert ACTUATOR.flow_factor(70.0, 0.002, load) == 1.0  # 0.9 m/s: below the rated 1.2 m/s
    factor = ACTUATOR.flow_factor(70.0, 0.005, load)  # 2.2 m/s asked
    error_m = abs(1 - ACTUATOR.gain(70.0, load, factor)) * 0.005
    overdrive = ACTUATOR.loop_gain_per_s * error_m / ACTUATOR.flow_limited_velocity_m_s
    assert factor == pytest.approx(saturation_gain(overdrive), abs=1e-9)
    achieved = abs(ACTUATOR.gain(70.0, load, factor))
    assert achieved < 0.8 < abs(ACTUATOR.gain(70.0, load))
    # a saturated valve delivers at most the square wave's fundamental of the rated velocity
    assert 2 * math.pi * 70.0 * achieved * 0.005 < 1.05 * 4 / math.pi * ACTUATOR.flow_limited_velocity_m_s
    # the plant streams the same equivalent gain
    bare = BenchSetup.paper_free_run()
    assert measured_gain(bare, 70.0, 0.005) == pytest.approx(ACTUATOR.gain(70.0, load, factor), rel=2e-4)


def test_describing_function_predicts_the_saturating_loop():
    """The true non-linear loop (a clipped valve command, integrated with RK45) against the
    describing function's amplitude: the valve lag and the oil column filter the harmonics the
    clipping makes, so the fundamental agrees within 3 %."""
    a = ACTUATOR
    mass_kg = a.moving_mass_kg + 12.0  # the bare plate
    freq_hz, amplitude_m = 60.0, 0.005
    w = 2 * math.pi * freq_hz

    def rates(t, x):
        z, v, c, q = x
        v_max = a.flow_limited_velocity_m_s
        command = min(max(a.loop_gain_per_s * (amplitude_m * math.sin(w * t) - z), -v_max), v_max)
        force_n = a.oil_stiffness_n_per_m * c
        return [v, force_n / mass_kg, q - v - a.bleed_rate_per_s * c, (command - q) / a.valve_time_constant_s]

    cycles, rate_hz = 30, 20_000.0
    t = np.arange(round(cycles * rate_hz / freq_hz)) / rate_hz
    sol = solve_ivp(rates, (0, t[-1]), [0, 0, 0, 0], t_eval=t, rtol=1e-8, atol=1e-12, max_step=1e-4)
    simulated = abs(fundamental(sol.y[0], freq_hz, rate_hz, 10))
    load = -12.0 * w**2
    predicted = abs(a.gain(freq_hz, load, a.flow_factor(freq_hz, amplitude_m, load))) * amplitude_m
    assert predicted < 0.8 * amplitude_m  # deep in the flow limit
    assert simulated == pytest.approx(predicted, rel=0.03)
