"""The dry run: predictions checked against closed forms, and points beyond a limit refused with
the point and the limit named."""

import dataclasses
import math

import numpy as np
import pytest

from bench.config import Specimen, default_bench_config
from bench.dry_run import STANDARD_GRAVITY_M_S2, DryRunError, dry_run
from bench.models.parameters import WfsSensor
from bench.models.setup import BenchSetup
from sequences import (
    AdaptiveDwell,
    DwellGrid,
    FreeRun,
    Prompt,
    Sequence,
    SineDwell,
    Sweep,
    Tare,
    load_sequence,
    shipped_file,
)

SHAKER = default_bench_config("shaker")
FOUR_POST = default_bench_config("four_post")


def _pressure(bar: float) -> Prompt:
    return Prompt(
        f"p{bar}",
        f"Set {bar} bar",
        answer="number",
        unit="bar",
        minimum=0.5,
        maximum=4.5,
        action="set_tyre_pressure",
        target=bar,
    )


def _with_limits(config, **limits):
    return dataclasses.replace(config, limits=dataclasses.replace(config.limits, **limits))


@pytest.mark.parametrize(
    ("name", "config", "points"),
    [
        ("paper_shaker.toml", SHAKER, 211),
        ("paper_shaker_adaptive.toml", SHAKER, 94 + 9),  # + the refinement band of 9 amplitudes
        ("smoke.toml", SHAKER, 8),
        ("paper_four_post.toml", FOUR_POST, 11),
    ],
)
def test_shipped_sequences_pass_on_their_simulated_bench(name, config, points):
    result = dry_run(load_sequence(shipped_file(name), config.limits), config)
    assert result.ok and len(result.points) == points
    result.check()


def test_wfs_overload_at_the_tread_resonance_is_refused_naming_point_and_limit():
    # Model 2 at 2.5 bar: the tread mass (6 kg) on the tyre spring (390 kN/m) resonates at
    # sqrt(k / m_T) / 2 pi = 40.6 Hz. The tread moves with the plate and the WFS (about 1800 times
    # stiffer than the tyre) holds the rim still, so the WFS carries about |k(f) + jwd| Z: with
    # k(40 Hz) = 390 kN/m (1 + 0.03 log10(40 / 10)) and wd about 5 % of k, 1.99 kN at 5 mm.
    sequence = Sequence("resonance", "", (_pressure(2.5), Tare(), SineDwell(40.0, 1.0), SineDwell(40.0, 5.0)))
    config = _with_limits(SHAKER, wfs_force_n=1000.0)
    result = dry_run(sequence, config)
    (refusal,) = result.refusals
    assert refusal.limit == "wfs_force_n" and refusal.allowed == 1000.0
    assert (refusal.point.step_index, refusal.point.freq_hz, refusal.point.amplitude_mm) == (3, 40.0, 5.0)
    k_40_hz = 390e3 * (1 + 0.03 * math.log10(40.0 / 10.0))
    assert refusal.predicted == pytest.approx(k_40_hz * 5e-3, rel=0.02)
    text = str(refusal)
    assert text.startswith("steps[3] point 0 (40 Hz, 5 mm): predicted WFS load ")
    assert text.endswith("is beyond the limit wfs_force_n = 1000 N")
    with pytest.raises(DryRunError) as info:
        result.check()
    assert str(info.value) == f"<script>: {text}"
    one_mm = result.points[0]
    assert one_mm.amplitude_mm == 1.0 and one_mm.wfs_load_n < 1000.0


def test_predictions_follow_the_last_pressure_prompt():
    dwell = SineDwell(40.0, 5.0)
    sequence = Sequence("p", "", (dwell, _pressure(1.5), dwell, _pressure(3.5), dwell))
    first, at_1_5, at_3_5 = dry_run(sequence, SHAKER).points
    assert [p.pressure_bar for p in (first, at_1_5, at_3_5)] == [2.5, 1.5, 3.5]  # configured, then prompts
    for point, bar in ((first, 2.5), (at_1_5, 1.5), (at_3_5, 3.5)):
        network = BenchSetup.paper_shaker(bar).operating_network(40.0, 5e-3)
        response = network.frequency_response(40.0, outputs=("f_wfs", "f_plate"))
        assert point.wfs_load_n == pytest.approx(abs(response["f_wfs"][0]) * 5e-3, rel=1e-12)
        assert point.actuator_force_n == pytest.approx(abs(response["f_plate"][0]) * 5e-3, rel=1e-12)


@pytest.mark.parametrize("freq_hz", [1.0, 12.0, 40.0, 70.0])
def test_model_1_linear_matches_its_closed_form(freq_hz):
    """One 29 kg wheel mass m between the tyre (k, d) on the plate and the WFS (k_s, d_s) on the
    clamped hub: X / Z = (k + jwd) / (k + k_s + jw(d + d_s) - w^2 m), F_WFS = (k_s + jw d_s) X,
    F_plate = (k + jwd)(Z - X) - m_plate w^2 Z; 500 N of tyre preload adds to the WFS load."""
    config = dataclasses.replace(SHAKER, specimen=Specimen(tyre_model=1, nonlinear=False, preload_n=500.0))
    amplitude_mm = 1.0
    (point,) = dry_run(Sequence("m1", "", (SineDwell(freq_hz, amplitude_mm),)), config).points
    w, Z = 2 * math.pi * freq_hz, amplitude_mm * 1e-3
    k, d, m, m_plate = 390e3, 80.0, 29.0, 12.0
    sensor = WfsSensor()
    k_s, d_s = sensor.stiffness_n_per_m, sensor.damping_ns_per_m
    X = (k + 1j * w * d) * Z / (k + k_s + 1j * w * (d + d_s) - w**2 * m)
    f_wfs = (k_s + 1j * w * d_s) * X
    f_plate = (k + 1j * w * d) * (Z - X) - m_plate * w**2 * Z
    assert point.wfs_static_n == 500.0
    assert point.wfs_load_n == pytest.approx(abs(f_wfs) + 500.0, rel=1e-9)
    assert point.actuator_force_n == pytest.approx(abs(f_plate), rel=1e-9)
    assert point.acceleration_m_s2 == pytest.approx(w**2 * Z, rel=1e-12)
    assert point.velocity_mm_s == pytest.approx(w * amplitude_mm, rel=1e-12)
    assert point.displacement_mm == amplitude_mm


def test_free_run_plate_force_is_plate_mass_times_acceleration():
    grid = DwellGrid((1.0, 10.0, 50.0, 100.0), (2.0,), max_acceleration_m_s2=500.0)
    result = dry_run(Sequence("free", "", (FreeRun(grid),)), SHAKER)
    for point, dwell in zip(result.points, grid.dwells(), strict=True):
        w = 2 * math.pi * dwell.freq_hz
        assert point.setup == "free_run" and point.wfs_load_n == 0.0 and point.pressure_bar is None
        assert point.amplitude_mm == dwell.amplitude_mm  # the amplitude actually used (100 Hz: limited)
        assert point.actuator_force_n == pytest.approx(12.0 * w**2 * dwell.amplitude_m, rel=1e-12)
        assert point.acceleration_m_s2 == pytest.approx(w**2 * dwell.amplitude_m, rel=1e-12)


def test_wheel_prompts_change_what_stands_on_the_bench():
    remove = Prompt("off", "Remove the wheel", action="remove_wheel")
    fit = Prompt("on", "Fit the wheel", action="fit_wheel")
    dwell = SineDwell(20.0, 2.0)
    points = dry_run(Sequence("w", "", (dwell, remove, dwell, fit, dwell)), SHAKER).points
    assert [p.setup for p in points] == ["shaker", "free_run", "shaker"]
    assert points[1].actuator_force_n == pytest.approx(12.0 * (2 * math.pi * 20.0) ** 2 * 2e-3, rel=1e-12)


def test_four_post_sweep_counts_the_weight_above_the_sensor():
    sequence = load_sequence(shipped_file("paper_four_post.toml"), FOUR_POST.limits)
    result = dry_run(sequence, FOUR_POST)
    sweep = result.points[-1]
    assert sweep.kind == "sweep" and sweep.setup == "quarter_car"
    assert sweep.wfs_static_n == pytest.approx((25.0 + 380.0) * STANDARD_GRAVITY_M_S2, rel=1e-12)
    # The reported peak is the network's response at the reported frequency, and no less than the
    # response at the wheel's own resonance inside the band.
    setup = BenchSetup.paper_quarter_car(2.5, model=2)
    setup = dataclasses.replace(setup, rig=dataclasses.replace(setup.rig, plate_mass_kg=15.0))

    def wfs_n(f):
        response = setup.operating_network(f, 2e-3).frequency_response(f, outputs=("f_wfs",))
        return abs(response["f_wfs"][0]) * 2e-3

    at = sweep.at_hz["wfs_load_n"]
    assert 0.1 <= at <= 30.0
    assert sweep.wfs_load_n - sweep.wfs_static_n == pytest.approx(wfs_n(at), rel=1e-9)
    wheel_hz = [f for f in setup.network().eigenfrequencies_hz() if 5 < f < 30]
    assert wheel_hz and all(sweep.wfs_load_n - sweep.wfs_static_n >= wfs_n(f) * (1 - 1e-9) for f in wheel_hz)


def test_sweep_refusal_names_the_frequency():
    sequence = Sequence("s", "", (Sweep(1.0, 30.0, 20.0, 2.0),))
    (refusal,) = dry_run(sequence, _with_limits(FOUR_POST, wfs_force_n=4000.0)).refusals
    assert refusal.limit == "wfs_force_n"
    assert str(refusal).startswith("steps[0] point 0 (sweep to 30 Hz, 2 mm): predicted WFS load")
    assert f"at {refusal.freq_hz:.4g} Hz is beyond" in str(refusal)


def test_actuator_force_and_kinematic_limits_are_checked():
    grid = DwellGrid((10.0, 60.0), (2.0,))
    config = _with_limits(SHAKER, force_n=1000.0, acceleration_m_s2=200.0)
    result = dry_run(Sequence("f", "", (FreeRun(grid),)), config)
    assert [(r.point.freq_hz, r.limit) for r in result.refusals] == [
        (60.0, "acceleration_m_s2"),
        (60.0, "force_n"),
    ]
    expected = 12.0 * (2 * math.pi * 60.0) ** 2 * 2e-3
    assert result.refusals[1].predicted == pytest.approx(expected, rel=1e-12)
    assert not np.isnan([p.actuator_force_n for p in result.points]).any()


def test_an_adaptive_grid_is_checked_where_its_refinement_may_add_points():
    """On the four-post bench the wheel-hop resonance (about 15 Hz) lies between coarse points at 5
    and 25 Hz: the coarse points pass a limit that a point added near the resonance would break."""
    grid = DwellGrid(freqs_hz=(5.0, 25.0), amplitudes_mm=(2.0,), adaptive=AdaptiveDwell())
    sequence = Sequence("adaptive", "", (grid,))
    *coarse, band = dry_run(sequence, FOUR_POST).points
    assert band.kind == "refinement" and 10.0 < band.at_hz["wfs_load_n"] < 20.0
    limit = (max(p.wfs_load_n for p in coarse) + band.wfs_load_n) / 2
    (refusal,) = dry_run(sequence, _with_limits(FOUR_POST, wfs_force_n=limit)).refusals
    assert refusal.point is not None and refusal.point.kind == "refinement"
    assert "points an adaptive grid may add up to 25 Hz" in str(refusal) and "wfs_force_n" in str(refusal)
