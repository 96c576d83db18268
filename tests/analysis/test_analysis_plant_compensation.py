"""Compensation on the simulated plant: shaker (model-based inverse against the 20x tread peak) and
four-post (raw, hub-acceleration and model-based valid bands), through the top-level API."""

import itertools

import numpy as np
import pytest

from bench.analysis.compensation import design_model_compensator
from bench.analysis.dwell import fit_dwell
from bench.models.benches import TyreModel
from bench.models.parameters import paper_tyre
from bench.models.setup import BenchSetup
from bench.simulated_campaign import simulate_dwells
from simulators.plant import PlantSimulator, SensorRealism, SineDwell
from tests.analysis.conftest import analyse_runs
from tests.documented import assert_documented

FS = 1000.0


def test_shaker_linear_model_compensation_to_70_hz(shaker_linear, free_run):
    """Linear tyre: the raw ratio peaks near 20x; the inverse of the identified model, as FIRs, must
    bring every dwell point to 1 within 10 % and 10 degrees up to 70 Hz (issue 3)."""
    result = analyse_runs([shaker_linear], free_run).nearest(shaker_linear.amplitude_m)
    assert np.max(np.abs(result.frfs.wfs_per_contact.value)) > 15
    ratio = result.compensated_per_contact.value
    assert np.max(np.abs(np.abs(ratio) - 1)) < 0.10
    assert np.max(np.abs(np.angle(ratio, deg=True))) < 10
    band = result.valid_band_compensated
    assert band.upper_hz == 70.0 and band.limited_by == "end of data"
    assert result.valid_band_raw.upper_hz < 15


def test_shaker_nonlinear_model_compensation_per_amplitude(shaker_nonlinear_campaign, capsys):
    """Non-linear tyre, each amplitude compensated with its own identification (k(f) and hysteretic
    damping included): report the worst deviation per amplitude, and require the 10 % / 10 degree
    band to reach 70 Hz for every amplitude (the rubber terms describe the simulator's linearised
    tyre at each dwell exactly, so only noise and FIR error remain)."""
    assert len(shaker_nonlinear_campaign.amplitudes) == 3
    for amp, result in shaker_nonlinear_campaign.amplitudes.items():
        ratio = result.compensated_per_contact.value
        worst_amp = np.max(np.abs(np.abs(ratio) - 1))
        worst_phase = np.max(np.abs(np.angle(ratio, deg=True)))
        with capsys.disabled():
            print(
                f"\n  shaker non-linear {amp * 1e3:.0f} mm: |H|-1 <= {100 * worst_amp:.2f} %,"
                f" phase <= {worst_phase:.2f} deg"
            )
        assert result.valid_band_compensated.upper_hz == 70.0


def test_streaming_equals_offline_and_matches_dwell():
    """The streaming filter fed in uneven blocks gives the offline output delayed by the latency."""
    setup = BenchSetup.paper_shaker(2.5, nonlinear=False)
    comp = design_model_compensator(TyreModel.WHEEL_TREAD, paper_tyre(2.5), setup.sensor, band_hz=80.0)
    rec = PlantSimulator(setup, realism=SensorRealism(seed=2)).simulate(
        SineDwell(freq_hz=30.0, amplitude=2e-3, hold_s=1.0, taper_in_s=0.3, taper_out_s=0.3)
    )
    offline = comp.apply(rec["fz_wfs_n"], rec["a_hub_m_s2"])
    stream = comp.stream()
    cuts = [0, 7, 300, 301, 999, rec["t_s"].size]
    streamed = np.concatenate(
        [stream.process(rec["fz_wfs_n"][a:b], rec["a_hub_m_s2"][a:b]) for a, b in itertools.pairwise(cuts)]
    )
    lat, n_taps = comp.latency_samples, comp.taps_wfs.size
    head = n_taps - 1 - lat  # offline outputs without a full input history are NaN
    assert np.all(np.isnan(offline[:head])) and np.all(np.isnan(offline[-lat:]))
    assert np.all(np.isfinite(offline[head:-lat]))
    # past the stream's start-up transient (its first n_taps - 1 outputs) both agree
    np.testing.assert_allclose(streamed[n_taps - 1 :], offline[head:-lat], rtol=1e-10, atol=1e-9)
    inner = slice(head, -lat)  # the same 0.5-1.3 s window of the record, in the finite part
    fit = fit_dwell(
        {"comp": offline[inner], "true": rec["f_contact_n"][inner]},
        FS,
        30.0,
        start_s=0.5 - head / FS,
        stop_s=1.3 - head / FS,
    )
    h, _ = fit.ratio("comp", "true")
    assert abs(h - 1) < 0.01


def test_four_post_valid_bands(four_post_analysis, capsys):
    """Four-post sweep with Model 2 or 3 as the truth. The model compensation uses the identification
    from the shaker campaign of the same tyre (Model 2 or 3 truth) at the same pressure and 2 mm, as
    a lab would; m_comp comes from the post's own free run, m_wheel and the accelerometer lag from
    the run itself. Issue 3: raw band <= 6 Hz, hub-acceleration compensated >= 12 Hz,
    model-compensated >= 25 Hz; m_wheel within 3 % of the 29 kg below the sensor."""
    setup, result = four_post_analysis
    assert result.post_free_run.plate.mass_kg == pytest.approx(setup.rig.plate_mass_kg, rel=0.01)
    mass = result.wheel_mass
    assert mass.mass_kg == pytest.approx(setup.tyre.wheel_mass_kg, rel=0.03)
    assert result.tyre_model is setup.model
    bands = {
        "raw": result.valid_band_raw,
        "accel": result.valid_band_hub_compensated,
        "model": result.valid_band_model_compensated,
    }
    with capsys.disabled():
        print(
            f"\n  four-post {setup.model.name}: m_wheel {mass.mass_kg:.2f} kg,"
            f" lag {1e3 * mass.accelerometer_delay_s:.3f} ms;"
            + "".join(f" {k} {b.upper_hz:.1f} Hz ({b.limited_by})" for k, b in bands.items())
        )
    # what docs/analysis.md quotes (seeded)
    assert_documented(
        "docs/analysis.md",
        f"Model {int(setup.model)} car: raw {bands['raw'].lowest_hz:.2f}-{bands['raw'].upper_hz:.4g} Hz,"
        f" hub acceleration {bands['accel'].lowest_hz:.2f}-{bands['accel'].upper_hz:.4g} Hz, model-based"
        f" {bands['model'].lowest_hz:.2f}-{bands['model'].upper_hz:.4g} Hz, m_wheel {mass.mass_kg:.2f} kg",
    )
    assert bands["raw"].upper_hz <= 6.0
    assert bands["accel"].upper_hz >= 12.0
    assert bands["model"].upper_hz >= 25.0


@pytest.mark.parametrize("freq_hz", [10.0, 38.0, 41.0, 60.0])
def test_shaker_compensator_out_of_sample_in_the_time_domain(shaker_nonlinear_campaign, freq_hz):
    """The compensator identified from the 2 mm grid, run through ``apply()`` on a new dwell (other
    noise seed, 3 mm: an amplitude it never saw) reads the true contact force within the issue's
    10 % / 10 degrees, also at the tread resonance (38-41 Hz) where the raw WFS over-reads ~15x.
    The rubber friction's damping at 3 mm differs from 2 mm by ~4 %, which bounds the error there."""
    comp = shaker_nonlinear_campaign.nearest(2e-3).compensator
    (record,) = simulate_dwells(BenchSetup.paper_shaker(2.5), [freq_hz], 3e-3, seed=77, include_truth=True)
    compensated = comp.apply(record.channels["fz_wfs_n"], record.channels["a_hub_m_s2"])
    finite = np.flatnonzero(np.isfinite(compensated))  # the aligned FIR output has NaN edges
    inner = slice(finite[0], finite[-1] + 1)
    start_s, stop_s = record.hold_s
    fit = fit_dwell(
        {
            "comp": compensated[inner],
            "true": record.channels["f_contact_n"][inner],
            "wfs": record.channels["fz_wfs_n"][inner],
        },
        FS,
        freq_hz,
        start_s=start_s + 0.2 - finite[0] / FS,
        stop_s=stop_s - finite[0] / FS,
    )
    h, _ = fit.ratio("comp", "true")
    raw, _ = fit.ratio("wfs", "true")
    assert abs(abs(h) - 1) < 0.10 and abs(np.angle(h, deg=True)) < 10.0, (abs(h), np.angle(h, deg=True))
    if 38.0 <= freq_hz <= 41.0:
        assert abs(raw) > 5.0  # the raw force is far off where the compensated one holds
