"""The simulated world: operator actions change the plant the way the real bench changes."""

import numpy as np
import pytest

from bench.models.benches import TyreModel
from bench.models.parameters import (
    PAPER_TYRE_STIFFNESS_N_PER_M,
    Tyre,
    TyreNonlinearity,
    paper_tyre,
    tyre_at_pressure,
)
from bench.models.setup import BenchKind, BenchSetup
from drivers.register_map import Command
from simulators.bench_sim import SimulatedBench
from simulators.plant import HalfSinePulse, PlantSimulator, SensorRealism
from simulators.world import DAMPER_SETTINGS_NS_PER_M, SimulatedOperator, SimulatedWorld

NO_NOISE = SensorRealism(noise=False, quantisation=False)


def make_world(**kwargs) -> SimulatedWorld:
    bench = SimulatedBench(PlantSimulator(BenchSetup.paper_free_run(), NO_NOISE))
    return SimulatedWorld(bench, **kwargs)


def start_dwell(bench: SimulatedBench) -> None:
    ctrl = bench.controller
    ctrl.write_setpoints({"waveform": 1, "frequency_hz": 10.0, "amplitude_mm": 1.0, "dwell_s": 5.0})
    for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH, Command.START):
        assert ctrl.command(command) is None
    bench.advance(100)


def test_tyre_stiffness_between_and_beyond_the_paper_pressures():
    for pressure in PAPER_TYRE_STIFFNESS_N_PER_M:
        assert tyre_at_pressure(pressure) == paper_tyre(pressure)
    assert tyre_at_pressure(2.4).stiffness_n_per_m == pytest.approx(250e3 + 0.9 * 140e3)
    assert tyre_at_pressure(3.0).stiffness_n_per_m == pytest.approx(405e3)
    assert tyre_at_pressure(1.0).stiffness_n_per_m == pytest.approx(180e3)  # end segment extended
    assert tyre_at_pressure(4.0).stiffness_n_per_m == pytest.approx(435e3)
    for outside in (0.9, 4.1):
        with pytest.raises(ValueError, match=r"outside 1\.0-4\.0 bar"):
            tyre_at_pressure(outside)


def test_answering_2_4_bar_gives_the_plant_a_2_4_bar_tyre():
    world = make_world()
    SimulatedOperator(world).apply("set_tyre_pressure", 2.4)
    plant = world.bench.plant
    tyre = Tyre(stiffness_n_per_m=376e3)
    expected = BenchSetup(BenchKind.SHAKER, TyreModel.WHEEL_TREAD, tyre, nonlinearity=TyreNonlinearity())
    assert plant.setup == expected
    reference = PlantSimulator(expected, NO_NOISE)
    for freq_hz in (10.0, 38.0, 60.0):
        assert plant.exact_response(freq_hz, 2e-3) == reference.exact_response(freq_hz, 2e-3)
        assert plant.base_gain(freq_hz, 2e-3) == reference.base_gain(freq_hz, 2e-3)
    at_2_5 = PlantSimulator(BenchSetup.paper_shaker(2.5), NO_NOISE).exact_response(38.0, 2e-3)
    assert abs(plant.exact_response(38.0, 2e-3)["f_wfs"] / at_2_5["f_wfs"] - 1) > 0.01


def test_the_wheel_off_leaves_the_plate_alone_and_back_on_restores_the_tyre():
    world = make_world(pressure_bar=1.5)
    operator = SimulatedOperator(world)
    operator.apply("remove_wheel", True)
    plant = world.bench.plant
    assert plant.setup.kind is BenchKind.FREE_RUN and plant.setup.rig.plate_mass_kg == 12.0
    out = plant.advance(1e-3 * np.sin(2 * np.pi * 20 * np.arange(5000) / 10_000))
    np.testing.assert_array_equal(out["fz_wfs_n"], 0.0)  # nothing on the sensor
    operator.apply("fit_wheel", True)
    assert plant.setup.kind is BenchKind.SHAKER and plant.setup.tyre == paper_tyre(1.5)
    out = plant.advance(1e-3 * np.sin(2 * np.pi * 20 * np.arange(5000) / 10_000))
    assert np.abs(out["fz_wfs_n"]).max() > 100.0


def test_a_declined_confirmation_changes_nothing():
    world = make_world()
    SimulatedOperator(world).apply("remove_wheel", False)
    assert world.bench.plant.setup.kind is BenchKind.SHAKER


def test_the_car_on_the_posts_with_each_damper_setting():
    world = make_world(kind="four_post", specimen_mounted=False)
    operator = SimulatedOperator(world)
    plant = world.bench.plant
    assert plant.setup.kind is BenchKind.FREE_RUN and plant.setup.rig.plate_mass_kg == 15.0
    operator.apply("car_on_posts", True)
    assert plant.setup.kind is BenchKind.QUARTER_CAR
    assert plant.setup.model is TyreModel.WHEEL_TREAD_SIDEWALL
    for setting, damping in DAMPER_SETTINGS_NS_PER_M.items():
        operator.apply("set_damper", setting)
        assert plant.setup.suspension.damping_ns_per_m == damping
    # a firmer damper damps the body mode more: the plant's response at the body mode falls
    firm = plant.exact_response(1.5, 2e-3)["a_hub"]
    operator.apply("set_damper", "soft")
    assert abs(plant.exact_response(1.5, 2e-3)["a_hub"]) > abs(firm)
    operator.apply("car_off_posts", True)
    assert plant.setup.kind is BenchKind.FREE_RUN


def test_no_change_while_the_actuator_moves_and_nothing_is_lost():
    world = make_world()
    start_dwell(world.bench)
    assert world.bench.moving
    with pytest.raises(RuntimeError, match="while the actuator is moving"):
        world.set_tyre_pressure(3.0)
    assert world.pressure_bar == 2.5 and world.bench.plant.setup.tyre == paper_tyre(2.5)
    world.bench.controller.command(Command.STOP)
    while world.bench.moving:
        world.bench.advance(100)
    world.set_tyre_pressure(3.0)
    assert world.bench.plant.setup.tyre == tyre_at_pressure(3.0)


@pytest.mark.parametrize(
    ("kwargs", "call", "message"),
    [
        ({}, lambda w: w.car_on_posts(), "not on the shaker bench"),
        ({"kind": "four_post"}, lambda w: w.fit_wheel(), "not on the four_post bench"),
        ({"kind": "four_post"}, lambda w: w.set_damper("stiff"), "unknown setting 'stiff'"),
        ({}, lambda w: w.set_tyre_pressure(6.0), "outside 1.0-4.0 bar"),
        ({}, lambda w: w.strike_hammer(), "remove the wheel"),
    ],
)
def test_actions_that_make_no_sense_are_refused(kwargs, call, message):
    world = make_world(**kwargs)
    before = world.bench.plant.setup
    with pytest.raises(ValueError, match=message):
        call(world)
    assert world.bench.plant.setup == before


def test_unknown_action_is_named():
    with pytest.raises(ValueError, match="unknown operator action 'paint_rim'"):
        SimulatedOperator(make_world()).apply("paint_rim", True)


def test_a_hammer_blow_on_the_bare_sensor_rings_at_its_eigenfrequency():
    world = make_world(specimen_mounted=False)
    SimulatedOperator(world).apply("strike_hammer", 2000.0)
    plant = world.bench.plant
    assert plant.setup.kind is BenchKind.HAMMER
    block = world.bench.advance(50)  # 50 ms
    assert block.fast_rate_hz == 10_000.0
    fz = block.fast["fz_wfs_n"]
    assert fz.size == 500
    np.testing.assert_array_equal(block.channels["z_base_m"], 0.0)
    spectrum = np.abs(np.fft.rfft(fz * np.hanning(fz.size), 1 << 16))
    peak_hz = np.fft.rfftfreq(1 << 16, 1e-4)[np.argmax(spectrum)]
    sensor = plant.setup.sensor
    assert peak_hz == pytest.approx(sensor.eigenfrequency_hz * np.sqrt(1 - sensor.damping_ratio**2), rel=0.01)
    # The plant sees the blow sampled at 10 kHz and linear between samples (u_k, spacing h): its
    # spectrum is h sinc^2(w h / 2) sum(u_k e^(-j w k h)), and a blow shorter than the period sets
    # the sensor ringing at w |F(w)| (k x = k v / w, v = |F| / m, k = m w^2), less ~3 % of decay
    # over the first quarter period at 2 % damping.
    w = 2 * np.pi * sensor.eigenfrequency_hz
    h = 1e-4
    k = np.arange(5)
    u = HalfSinePulse(2000.0, width_s=1.5e-4, delay_s=0.0, record_s=1.5e-4).value(k * h)
    spectrum_n_s = h * np.sinc(w * h / (2 * np.pi)) ** 2 * abs(np.sum(u * np.exp(-1j * w * k * h)))
    assert np.abs(fz).max() == pytest.approx(w * spectrum_n_s, rel=0.05)
    SimulatedOperator(world).apply("remove_wheel", True)  # back on the bench: the plate alone again
    assert plant.setup.kind is BenchKind.FREE_RUN
