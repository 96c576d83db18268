"""Bench models against closed forms, statics and the paper's findings (section 4)."""

import math

import numpy as np
import pytest

from bench.models.benches import TyreModel, free_run, hammer_test, quarter_car, shaker_bench
from bench.models.network import Base, Link, Mass, MechanicalNetwork
from bench.models.parameters import (
    PAPER_TYRE_STIFFNESS_N_PER_M,
    Rig,
    Suspension,
    Tyre,
    TyreNonlinearity,
    WfsSensor,
    paper_tyre,
)
from bench.models.setup import BenchSetup

FREQ_HZ = np.linspace(0.5, 70.0, 2000)
MODELS = list(TyreModel)


def ratio(network: MechanicalNetwork, freq_hz=FREQ_HZ) -> np.ndarray:
    r = network.frequency_response(freq_hz)
    return r["f_wfs"] / r["f_contact"]


def test_model2_shaker_equals_closed_form_in_rigid_sensor_limit():
    """Hub fixed and a rigid sensor: F_WFS/F_contact = (k + jwd) / (k - m_T w^2 + jwd).

    A sensor of 1e15 N/m leaves a physical deviation of m_rim w^2 / k_s < 1e-8 at 70 Hz.
    """
    tyre = paper_tyre(2.5)
    rigid = WfsSensor(eigenfrequency_hz=2.5e6, damping_ratio=0.0)
    assert rigid.stiffness_n_per_m > 9e14
    w = 2 * np.pi * FREQ_HZ
    k, d, m_t = tyre.stiffness_n_per_m, tyre.damping_ns_per_m, tyre.tread_mass_kg
    closed = (k + 1j * w * d) / (k - m_t * w**2 + 1j * w * d)
    np.testing.assert_allclose(ratio(shaker_bench(TyreModel.WHEEL_TREAD, tyre, rigid)), closed, rtol=1e-6)


def _series(*stiffness):
    return 1.0 / sum(1.0 / k for k in stiffness)


@pytest.mark.parametrize("model", MODELS)
def test_shaker_static_gain_is_the_series_stiffness(model):
    tyre, sensor = paper_tyre(1.5), WfsSensor()
    tyre_static = tyre.stiffness_n_per_m
    if model is TyreModel.WHEEL_TREAD_SIDEWALL:
        tyre_static += _series(tyre.sidewall_lower_stiffness_n_per_m, tyre.sidewall_upper_stiffness_n_per_m)
    r = shaker_bench(model, tyre, sensor).frequency_response(0.0)
    expected = _series(tyre_static, sensor.stiffness_n_per_m)
    assert r["f_wfs"][0].real == pytest.approx(expected, rel=1e-9)
    assert r["f_contact"][0].real == pytest.approx(expected, rel=1e-9)
    assert r["f_plate"][0].real == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("model", MODELS)
def test_quarter_car_quasi_static_limit_is_the_mass_share_above_the_sensor(model):
    """At very low frequency the whole car moves with the post: the sensor carries the inertia of
    the masses above it, the contact that of the whole car (the tread is on the car's side of the
    contact). Spring and damper corrections are O(f / f_body) ~ 1e-3 at 1 mHz times d/k terms."""
    tyre, suspension = paper_tyre(2.5), Suspension()
    net = quarter_car(model, tyre, suspension)
    above = suspension.unsprung_mass_above_kg + suspension.body_mass_kg
    r = net.frequency_response(1e-3)
    assert abs(r["f_wfs"][0] / r["f_contact"][0]) == pytest.approx(
        above / (above + tyre.wheel_mass_kg), rel=1e-5
    )


def test_free_run_plate_force_is_plate_inertia():
    rig = Rig(plate_mass_kg=17.3)
    r = free_run(rig).frequency_response(FREQ_HZ)
    w = 2 * np.pi * FREQ_HZ
    np.testing.assert_allclose(r["f_plate"] / (-(w**2)), 17.3, rtol=1e-12)
    np.testing.assert_allclose(r["f_contact"], 0.0, atol=1e-12)


def test_plate_force_exceeds_contact_force_by_the_plate_inertia():
    rig = Rig(plate_mass_kg=12.0)
    r = shaker_bench(TyreModel.WHEEL_TREAD, paper_tyre(2.5), rig=rig).frequency_response(FREQ_HZ)
    np.testing.assert_allclose(r["f_plate"] - r["f_contact"], 12.0 * r["a_base"], rtol=1e-12, atol=1e-6)


@pytest.mark.parametrize("pressure_bar", sorted(PAPER_TYRE_STIFFNESS_N_PER_M))
def test_paper_shaker_peak_model2(pressure_bar):
    """Paper 4.1: F_WFS/F_contact rises from about 10 Hz to about 20x at 30-50 Hz with a phase
    change of about 180 degrees, then falls below 1 by 70 Hz."""
    h = ratio(shaker_bench(TyreModel.WHEEL_TREAD, paper_tyre(pressure_bar)))
    i = int(np.argmax(np.abs(h)))
    assert 15.0 <= abs(h[i]) <= 25.0
    assert 30.0 <= FREQ_HZ[i] <= 50.0
    assert abs(h[-1]) < 1.0
    assert abs(h[np.searchsorted(FREQ_HZ, 10.0)]) < 1.15  # only starting to rise at 10 Hz
    phase_before = np.angle(h[np.searchsorted(FREQ_HZ, 0.5 * FREQ_HZ[i])], deg=True)
    phase_after = np.angle(h[np.searchsorted(FREQ_HZ, min(1.5 * FREQ_HZ[i], 70.0))], deg=True)
    assert abs(abs(phase_before - phase_after) - 180.0) < 25.0


def test_paper_shaker_peak_rises_with_pressure_and_model1_has_none():
    peaks = []
    for pressure_bar in sorted(PAPER_TYRE_STIFFNESS_N_PER_M):
        h = ratio(shaker_bench(TyreModel.WHEEL_TREAD, paper_tyre(pressure_bar)))
        peaks.append((abs(h).max(), FREQ_HZ[np.argmax(abs(h))]))
        # Model 1 cannot show the tread resonance (paper 4.1): within 2 % of 1 everywhere.
        h1 = ratio(shaker_bench(TyreModel.WHEEL, paper_tyre(pressure_bar)))
        assert np.max(np.abs(np.abs(h1) - 1)) < 0.02
    amplitudes, freqs = zip(*peaks, strict=True)
    assert list(amplitudes) == sorted(amplitudes)
    assert list(freqs) == sorted(freqs)


def test_model3_follows_model2_on_the_shaker_up_to_the_peak():
    """The paper: Models 2 and 3 both simulate the shaker test; the sidewall has low sensitivity.

    Model 3's 1 kg sidewall, nearly rigid to the tread, adds to the moving tread mass and lowers
    the resonance by about 4 %, which moves the ratio by up to 11 % on the way to it at 30 Hz;
    15 % bounds that and still fails a model whose sidewall path carried real weight."""
    f = np.linspace(0.5, 30.0, 200)
    h2 = ratio(shaker_bench(TyreModel.WHEEL_TREAD, paper_tyre(2.5)), f)
    h3 = ratio(shaker_bench(TyreModel.WHEEL_TREAD_SIDEWALL, paper_tyre(2.5)), f)
    np.testing.assert_allclose(np.abs(h3), np.abs(h2), rtol=0.15)


def test_quarter_car_eigenfrequencies_where_the_parameters_put_them():
    """Two-mass decoupling: body on the series spring, wheel between tyre and suspension springs.

    The decoupled estimates neglect the coupling through the suspension spring, an error of order
    k_s / k_t ~ 10 % on the wheel mass's effective stiffness, hence a 5 % tolerance on frequency.
    """
    tyre, s = paper_tyre(2.5), Suspension()
    f = quarter_car(TyreModel.WHEEL, tyre, s).eigenfrequencies_hz()
    k_t = tyre.stiffness_n_per_m
    body = math.sqrt(_series(k_t, s.stiffness_n_per_m) / s.body_mass_kg) / (2 * math.pi)
    wheel = math.sqrt((k_t + s.stiffness_n_per_m) / (tyre.wheel_mass_kg + s.unsprung_mass_above_kg)) / (
        2 * math.pi
    )
    assert f[0] == pytest.approx(body, rel=0.05)
    assert f[1] == pytest.approx(wheel, rel=0.05)
    assert 12.0 < f[1] < 17.0  # the paper's "about 15 Hz"


def test_quarter_car_ratio_tends_to_the_mass_split_above_the_wheel_eigenfrequency():
    """Body still, sensor rigid: F_WFS/F_contact -> m_above / (m_above + m_below).

    The suspension damper still passes d*w*Z to the body, a relative error d/(m_above w) that
    falls as 1/f, so the ratio approaches the split as frequency rises (until the rim-on-sensor
    mode near 1 kHz ends the rigid-sensor range).
    """
    tyre, s = paper_tyre(2.5), Suspension()
    split = s.unsprung_mass_above_kg / (s.unsprung_mass_above_kg + tyre.wheel_mass_kg)
    f = np.array([30.0, 60.0, 120.0])
    errors = np.abs(np.abs(ratio(quarter_car(TyreModel.WHEEL, tyre, s), f)) - split)
    assert np.all(np.diff(errors) < 0)
    assert errors[-1] < 0.03 * split
    assert 0.4 < split < 0.55  # the paper's "about 50 %"


def test_hammer_test_rings_at_the_sensor_eigenfrequency():
    sensor = WfsSensor(mass_kg=3.82, eigenfrequency_hz=2300.0, damping_ratio=0.03)
    f = hammer_test(sensor).eigenfrequencies_hz()
    assert f[0] == pytest.approx(2300.0, rel=1e-9)


@pytest.mark.parametrize(
    "network",
    [
        shaker_bench(TyreModel.WHEEL, paper_tyre(1.5)),
        shaker_bench(TyreModel.WHEEL_TREAD_SIDEWALL, paper_tyre(3.5)),
        quarter_car(TyreModel.WHEEL_TREAD_SIDEWALL, paper_tyre(2.5)),
    ],
)
def test_state_space_and_dynamic_stiffness_give_the_same_response(network):
    f = np.array([0.7, 5.0, 14.0, 40.0, 90.0])
    w = 2 * np.pi * f
    direct = network.frequency_response(f)
    ss = network.state_space()
    per_input = {name: ss.frequency_response(f, name) for name in ("z_base", "v_base", "a_base")}
    for out in ("f_wfs", "f_contact", "f_plate", "a_hub", "z_rim"):
        combined = (
            per_input["z_base"][out] + 1j * w * per_input["v_base"][out] - w**2 * per_input["a_base"][out]
        )
        np.testing.assert_allclose(combined, direct[out], rtol=1e-7, atol=1e-9 * np.abs(direct[out]).max())


def test_nonlinear_tyre_amplitudes_differ_near_the_peak_only():
    """Paper Fig. 6: 1/2/5 mm curves match at most frequencies and differ near the maximum."""
    setup = BenchSetup.paper_shaker(2.5, nonlinear=True)
    away = [2.0, 10.0, 20.0, 65.0]

    def h(freq, amp):
        r = setup.operating_network(freq, amp).frequency_response(freq)
        return complex(r["f_wfs"][0] / r["f_contact"][0])

    peaks = [max(abs(h(f, a)) for f in np.linspace(36, 46, 41)) for a in (0.001, 0.002, 0.005)]
    assert peaks[0] < peaks[1] < peaks[2]  # friction damping falls with amplitude
    assert peaks[2] / peaks[0] > 1.15
    for f in away:
        values = [abs(h(f, a)) for a in (0.001, 0.002, 0.005)]
        assert max(values) / min(values) < 1.03


def test_a_kept_balance_is_the_one_solved_for_its_own_setup_and_operating_point():
    """The balances are kept per setup and operating point: asked again, the same tyre comes back;
    another pressure, amplitude or frequency has a balance of its own, the one solved afresh."""
    from bench.models.setup import _balanced_tyre

    at_2_5, at_1_5 = BenchSetup.paper_shaker(2.5), BenchSetup.paper_shaker(1.5)
    first = at_2_5.linear_tyre(40.0, 0.002)
    assert at_2_5.linear_tyre(40.0, 0.002) is first
    others = {
        "pressure": at_1_5.linear_tyre(40.0, 0.002),
        "amplitude": at_2_5.linear_tyre(40.0, 0.005),
        "frequency": at_2_5.linear_tyre(41.0, 0.002),
    }
    kept = {name: tyre.damping_ns_per_m for name, tyre in others.items()}
    _balanced_tyre.cache_clear()
    assert at_2_5.linear_tyre(40.0, 0.002) == first
    assert at_1_5.linear_tyre(40.0, 0.002).damping_ns_per_m == kept["pressure"]
    assert at_2_5.linear_tyre(40.0, 0.005).damping_ns_per_m == kept["amplitude"]
    assert at_2_5.linear_tyre(41.0, 0.002).damping_ns_per_m == kept["frequency"]
    assert len({first.damping_ns_per_m, *kept.values()}) == 4


def test_nonlinear_stiffness_rises_with_frequency():
    law, tyre = TyreNonlinearity(), paper_tyre(2.5)
    k = [law.linearised(tyre, f, 0.002).stiffness_n_per_m for f in (1.0, 10.0, 70.0)]
    assert k[0] < k[1] < k[2]
    assert k[1] == pytest.approx(tyre.stiffness_n_per_m)  # reference frequency


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: MechanicalNetwork([Mass("a", -1.0)], []), "must be positive"),
        (lambda: MechanicalNetwork([Mass("a", 1.0)], [Link("l", "a", "nowhere", 1.0)]), "unknown node"),
        (lambda: MechanicalNetwork([Mass("a", 1.0), Mass("a", 2.0)], []), "unique"),
        (lambda: MechanicalNetwork([Mass("a", 1.0)], [Link("l", "a", "ground", -5.0)]), "negative"),
        (lambda: MechanicalNetwork([Mass("a", 1.0)], [], base=Base(), force_inputs=["b"]), "not a free mass"),
        (lambda: Tyre(stiffness_n_per_m=0.0), "positive"),
        (lambda: Tyre(stiffness_n_per_m=1e5, tread_mass_kg=30.0), "rim mass"),
        (lambda: WfsSensor(mass_kg=0.0), "invalid sensor"),
        (lambda: paper_tyre(2.0), "known pressures"),
        (lambda: Suspension(body_mass_kg=-1.0), "positive"),
    ],
)
def test_invalid_parameters_are_refused_with_a_clear_message(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_unknown_frequency_response_input_is_refused():
    with pytest.raises(ValueError, match="unknown input"):
        shaker_bench(TyreModel.WHEEL, paper_tyre(2.5)).frequency_response(10.0, "f_rim")
