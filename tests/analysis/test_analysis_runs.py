"""The top-level API on whole simulated runs: results against the simulator's truth, what the summaries
state, and garbage records named in clear errors or flagged."""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from bench.analysis import (
    AnalysisInputError,
    DwellRecord,
    HammerRecord,
    analyse_four_post,
    analyse_hammer,
    analyse_shaker_campaign,
)
from bench.analysis.frf import valid_band
from bench.analysis.tyre_fit import amplitude_dependence
from bench.models.benches import TyreModel
from bench.models.parameters import WfsSensor
from bench.models.setup import BenchKind, BenchSetup
from bench.report.text import summary_lines
from bench.simulated_campaign import SHAKER_GRID_HZ, simulate_dwells
from simulators.plant import HalfSinePulse, PlantSimulator, SensorRealism
from tests.analysis.conftest import same_tyre_campaign
from tests.documented import assert_documented


def _campaign(records, free_run, setup):
    return analyse_shaker_campaign(
        records, free_run.records, wheel_mass_kg=setup.tyre.wheel_mass_kg, sensor=setup.sensor
    )


def test_shaker_campaign_recovers_other_tyre(shaker_other_tyre, free_run):
    """A tyre that is not the paper's, through the API: m_comp within 1 %, and the issue's tolerances
    for the selected model (k 2 %, tread mass 3 %, damping 15 %; the dwells are accurate to ~1e-4,
    so a real bias such as a lost plate-mass correction fails them). Model 2, the truth, must be
    selected; Model 3's sidewall must be reported as not determined, in the result and the summary."""
    setup = shaker_other_tyre.plant.setup
    result = _campaign(shaker_other_tyre.records, free_run, setup)
    assert result.free_run.plate.mass_kg == pytest.approx(free_run.plant.setup.rig.plate_mass_kg, rel=0.01)
    amp = result.nearest(2e-3)
    assert list(result.amplitudes) == [2e-3]
    ident = amp.identification
    assert ident.best is TyreModel.WHEEL_TREAD
    truth = setup.tyre
    fit = ident.best_fit.tyre
    assert fit.stiffness_n_per_m == pytest.approx(truth.stiffness_n_per_m, rel=0.02)
    assert fit.tread_mass_kg == pytest.approx(truth.tread_mass_kg, rel=0.03)
    assert fit.damping_ns_per_m == pytest.approx(truth.damping_ns_per_m, rel=0.15)
    assert "sidewall_mass_kg" in ident.fits[TyreModel.WHEEL_TREAD_SIDEWALL].undetermined
    assert amp.unsettled == () and amp.frfs.wfs_per_z.reliable.all()
    # the compensator inverts the identified model over the whole grid; the raw ratio does not
    assert amp.valid_band_compensated.upper_hz == 70.0
    assert amp.valid_band_raw.upper_hz < 15.0
    assert result.amplitude_dependence is None

    text = "\n".join(summary_lines(result))
    assert "m_comp" in text and "kg" in text
    assert f"raw {amp.valid_band_raw.lowest_hz:.4g}-{amp.valid_band_raw.upper_hz:.4g} Hz" in text
    assert "model-compensated 0.5-70 Hz" in text
    assert "2 mm not determined: " in text and "sidewall_mass_kg" in text
    assert "amplitude dependence: not determined (one amplitude only)" in text
    assert "FLAG" not in text


def test_amplitude_dependence_from_the_campaign(shaker_nonlinear_campaign, shaker_nonlinear):
    """The non-linear tyre at 1 / 2 / 5 mm: the plant's friction damping falls with amplitude while
    its stiffness does not depend on it. The equivalent damping at each fit's tread resonance must
    match the plant's linearised tyre there within the issue's 15 %, k change below 1 %."""
    dep = shaker_nonlinear_campaign.amplitude_dependence
    assert dep is not None
    np.testing.assert_array_equal(dep.amplitude_m, [1e-3, 2e-3, 5e-3])
    assert np.max(np.abs(dep.stiffness_change)) < 0.01
    assert dep.damping_change[1] < -0.05 and dep.damping_change[2] < dep.damping_change[1]
    for amp, fit, d in zip(dep.amplitude_m, dep.fits, dep.equivalent_damping_ns_per_m, strict=True):
        f_res = np.sqrt(fit.tyre.stiffness_n_per_m / fit.tyre.tread_mass_kg) / (2 * np.pi)
        truth = shaker_nonlinear[amp].plant.setup.linear_tyre(f_res, amp)
        assert d == pytest.approx(truth.damping_ns_per_m, rel=0.15)
    text = "\n".join(summary_lines(shaker_nonlinear_campaign))
    assert "amplitude dependence (Model 2" in text
    assert all(f"{mm} mm valid band" in text for mm in (1, 2, 5))


def test_campaign_reuses_the_identifications_fits_for_the_amplitude_dependence(shaker_nonlinear_campaign):
    """Each identification fits every model variant once and keeps them all (Model 2 with the four
    combinations of rubber terms among them); the campaign's amplitude dependence is the same
    objects, and equals the dependence fitted afresh from the FRFs."""
    campaign = shaker_nonlinear_campaign
    for result in campaign.amplitudes.values():
        tried = result.identification.tried
        assert {(TyreModel.WHEEL_TREAD, r, h) for r in (False, True) for h in (False, True)} <= set(tried)
        assert all(fit in tried.values() for fit in result.identification.fits.values())
    dep = campaign.amplitude_dependence
    rate = any(r.identification.frequency_dependent_stiffness for r in campaign.amplitudes.values())
    hyst = any(r.identification.hysteretic_damping for r in campaign.amplitudes.values())
    for amp, fit in zip(dep.amplitude_m, dep.fits, strict=True):
        assert fit is campaign.amplitudes[amp].identification.tried[(TyreModel.WHEEL_TREAD, rate, hyst)]
    fresh = amplitude_dependence(
        {a: (r.frfs.wfs_per_z, r.frfs.contact_per_z) for a, r in campaign.amplitudes.items()},
        wheel_mass_kg=campaign.wheel_mass_kg,
        sensor=campaign.sensor,
        stiffness_rise=rate,
        hysteretic=hyst,
        errors={a: r.frfs.errors for a, r in campaign.amplitudes.items()},
    )
    columns = ("stiffness_n_per_m", "stiffness_ci95_n_per_m", "equivalent_damping_ns_per_m", "tread_mass_kg")
    for name in columns:
        np.testing.assert_array_equal(getattr(fresh, name), getattr(dep, name))


def test_four_post_result_and_summary(four_post_analysis):
    """The four-post result states m_wheel, the three valid bands, the quarter car with its modes,
    what it does not determine and took as given, and flags the sweep's unreliable flank bins."""
    setup, result = four_post_analysis
    assert result.wheel_mass_given_kg == setup.tyre.wheel_mass_kg
    assert result.tyre_source == "the shaker identification at 2 mm"
    # the hub-acceleration relation: m_h + m_B below the body mode, m_h well above it
    m = result.apparent_mass_above
    low = m.reliable & (m.freq_hz < 3.0)
    truth = setup.suspension
    assert np.median(np.abs(m.value[low])) > truth.unsprung_mass_above_kg + 0.5 * truth.body_mass_kg
    high = m.reliable & (m.freq_hz > 20.0)
    assert np.abs(m.value[high]).max() < 2 * truth.unsprung_mass_above_kg
    assert result.unreliable_bins > 0  # the flanks of a 0.1-30 Hz sweep over 60 s
    # the bins reliable in all three FRFs over Z: what docs/analysis.md quotes (seeded)
    frfs = result.frfs
    over_z = frfs.wfs_per_z.reliable & frfs.contact_per_z.reliable & frfs.accel_per_z.reliable
    f = frfs.wfs_per_z.freq_hz[over_z]
    assert_documented("docs/analysis.md", f"the reliable band over Z is {f.min():.3g}-{f.max():.4g} Hz")
    text = "\n".join(summary_lines(result))
    for band, name in (
        (result.valid_band_raw, "raw"),
        (result.valid_band_hub_compensated, "hub-acceleration compensated"),
        (result.valid_band_model_compensated, "model-compensated"),
    ):
        assert f"{name} {band.lowest_hz:.4g}-{band.upper_hz:.4g} Hz" in text
    assert "m_wheel" in text and "accelerometer lag" in text and "body" in text and "wheel" in text
    assert "quarter car not determined: none" in text  # the full band determines the car
    assert "quarter car taken as given: " in text and "FLAG" in text and "unreliable" in text


def test_four_post_with_a_tyre_fit(four_post, four_post_free_run, request):
    """Given one identification instead of a campaign, the compensator is designed over the sweep's
    band (1.15 x 30 Hz): the issue's model-compensated band of at least 25 Hz must still hold."""
    setup, sweep = four_post
    fit = same_tyre_campaign(setup, request).nearest(2e-3).identification.best_fit
    result = analyse_four_post(
        sweep, four_post_free_run.records, tyre=fit, wheel_mass_kg=29.0, sensor=setup.sensor
    )
    assert result.compensator.band_hz == pytest.approx(1.15 * 30.0)
    assert result.valid_band_model_compensated.upper_hz >= 25.0
    assert result.tyre_source == "a given shaker identification"
    with pytest.raises(AnalysisInputError, match="tyre_model"):
        analyse_four_post(
            sweep, four_post_free_run.records, tyre=setup.tyre, wheel_mass_kg=29.0, sensor=setup.sensor
        )
    with pytest.raises(AnalysisInputError, match="wheel mass 30 kg differs"):
        analyse_four_post(
            sweep, four_post_free_run.records, tyre=fit, wheel_mass_kg=30.0, sensor=setup.sensor
        )


def _hammer_record(sensor, seed, fs=10_000.0):
    plant = PlantSimulator(
        BenchSetup(BenchKind.HAMMER, sensor=sensor), realism=SensorRealism(seed=seed), output_rate_hz=fs
    )
    rec = plant.simulate(HalfSinePulse(amplitude=3000.0, width_s=1.5e-4, delay_s=0.02, record_s=0.3))
    return HammerRecord(fs, rec)


def test_hammer_through_the_api():
    """A sensor that is not the paper's: the issue's 1 % on the eigenfrequency and 10 % on both
    damping ratios; the summary states both and flags nothing; a missing channel names the record."""
    sensor = WfsSensor(mass_kg=2.9, eigenfrequency_hz=1650.0, damping_ratio=0.035)
    record = _hammer_record(sensor, seed=6)
    res = analyse_hammer(record, sensor_mass_kg=sensor.mass_kg)
    assert res.eigenfrequency_hz == pytest.approx(sensor.eigenfrequency_hz, rel=0.01)
    assert res.damping_ratio_half_power == pytest.approx(sensor.damping_ratio, rel=0.10)
    assert res.damping_ratio_log_decrement == pytest.approx(sensor.damping_ratio, rel=0.10)
    text = "\n".join(summary_lines(res))
    assert "Hz" in text and "half-power" in text and "logarithmic decrement" in text
    assert "FLAG" not in text
    flagged = replace(res, damping_ratio_half_power=2 * res.damping_ratio_log_decrement)
    assert any(line.startswith("FLAG") for line in summary_lines(flagged))
    with pytest.raises(AnalysisInputError, match="hammer blow at 10000 Hz sampling: no channel 'fz_wfs_n'"):
        analyse_hammer(
            HammerRecord(record.sample_rate_hz, {"f_hammer_n": record.channels["f_hammer_n"]}),
            sensor_mass_kg=2.9,
        )


def _broken(record: DwellRecord, channel: str, values) -> DwellRecord:
    return replace(record, channels={**record.channels, channel: values})


def test_garbage_records_name_the_record(shaker_linear, free_run):
    setup = shaker_linear.plant.setup
    records = shaker_linear.records
    i = 12  # the 34 Hz dwell
    nan = records[i].channels["fz_wfs_n"].copy()
    nan[100] = np.nan
    cases = {
        "dwell 2 mm at 34 Hz: channel 'fz_wfs_n' has 1 non-finite": _broken(records[i], "fz_wfs_n", nan),
        "dwell 2 mm at 34 Hz: channels have different lengths": _broken(
            records[i], "a_hub_m_s2", records[i].channels["a_hub_m_s2"][:-5]
        ),
    }
    for message, bad in cases.items():
        garbage = [*records[:i], bad, *records[i + 1 :]]
        with pytest.raises(AnalysisInputError, match=message):
            _campaign(garbage, free_run, setup)
    with pytest.raises(AnalysisInputError, match="shaker campaign: no dwell records"):
        _campaign([], free_run, setup)
    with pytest.raises(AnalysisInputError, match="free run: no dwell records"):
        analyse_shaker_campaign(records, [], wheel_mass_kg=29.0, sensor=setup.sensor)
    with pytest.raises(AnalysisInputError, match="different sample rates"):
        _campaign([*records[:-1], replace(records[-1], sample_rate_hz=999.0)], free_run, setup)
    # a dwell recorded twice is a repeat, combined (docs/analysis.md), not an error
    twice = _campaign([*records, records[i - 1]], free_run, setup).nearest(2e-3)
    assert len(twice.fits) == len(records) and [r.n for r in twice.repeats] == [2]
    # a dwell without the hub acceleration: the clamped hub needs none, so the amplitude is analysed
    # without it (taken as not moving), not refused
    no_hub = replace(records[i], channels={k: v for k, v in records[i].channels.items() if k != "a_hub_m_s2"})
    amplitude = _campaign([*records[:i], no_hub, *records[i + 1 :]], free_run, setup).nearest(2e-3)
    assert not amplitude.hub_acceleration_recorded and len(amplitude.fits) == len(records)


def test_unsettled_dwell_is_flagged_and_left_out(shaker_linear, free_run):
    """A dwell whose hold is stated 0.3 s too early (the analysed window then starts in the taper-in)
    cannot pass the settling test: its point is unreliable, left out of the fits, and the summary
    says which."""
    setup = shaker_linear.plant.setup
    records = list(shaker_linear.records)
    i = 5  # the 10 Hz dwell
    start, stop = records[i].hold_s
    records[i] = replace(records[i], hold_s=(start - 0.3, stop - 0.3))
    result = _campaign(records, free_run, setup).nearest(2e-3)
    assert not result.frfs.wfs_per_z.reliable[i] and result.frfs.wfs_per_z.reliable.sum() == len(records) - 1
    assert len(result.unsettled) == 1 and result.unsettled[0].startswith("dwell 2 mm at 10 Hz")
    flags = [line for line in summary_lines(result) if line.startswith("FLAG")]
    assert len(flags) == 1 and "not settled: dwell 2 mm at 10 Hz" in flags[0]
    # the other 21 dwells still identify the tyre (issue tolerance on k)
    k = result.identification.best_fit.tyre.stiffness_n_per_m
    assert k == pytest.approx(setup.tyre.stiffness_n_per_m, rel=0.02)


def test_garbage_sweep_names_the_record(four_post, four_post_free_run, shaker_nonlinear_campaign):
    setup, sweep = four_post
    kw = {"tyre": shaker_nonlinear_campaign, "wheel_mass_kg": 29.0, "sensor": setup.sensor}
    nan = sweep.channels["f_plate_n"].copy()
    nan[-1] = np.nan
    with pytest.raises(
        AnalysisInputError, match=r"sweep 0\.1-30 Hz at 2 mm: channel 'f_plate_n' has 1 non-finite"
    ):
        analyse_four_post(
            replace(sweep, channels={**sweep.channels, "f_plate_n": nan}), four_post_free_run.records, **kw
        )
    # a truncated record (20 s of the 60 s sweep reach only ~10 Hz; 2 s barely start it) is refused
    for seconds in (20, 2):
        short = replace(sweep, channels={k: v[: seconds * 1000] for k, v in sweep.channels.items()})
        with pytest.raises(
            AnalysisInputError,
            match=rf"sweep 0\.1-30 Hz at 2 mm: the record is {seconds} s long but the sweep takes 60 s",
        ):
            analyse_four_post(short, four_post_free_run.records, **kw)
    # a whole sweep too short for the wheel mass band: the error names the record, no internal channel
    short = replace(sweep, sweep_s=2.0, channels={k: v[:2000] for k, v in sweep.channels.items()})
    with pytest.raises(AnalysisInputError, match=r"sweep 0\.1-30 Hz at 2 mm: ") as err:
        analyse_four_post(short, four_post_free_run.records, **kw)
    assert "too short for the wheel mass band from 1 Hz" in str(err.value)
    assert "f_contact" not in str(err.value)
    with pytest.raises(AnalysisInputError, match="sweep band must satisfy"):
        analyse_four_post(replace(sweep, end_hz=600.0), four_post_free_run.records, **kw)


def test_one_point_band_is_reported_not_determined(shaker_other_tyre, free_run):
    """A band in which a single point passes (here the lowest dwell, the next one unreliable) has no
    width: the summary must not print it as a band 'f-f Hz'."""
    setup = shaker_other_tyre.plant.setup
    amp = _campaign(shaker_other_tyre.records, free_run, setup).nearest(2e-3)
    raw = amp.frfs.wfs_per_contact
    reliable = raw.reliable.copy()
    reliable[1] = False
    band = valid_band(raw.freq_hz, raw.value, reliable, sigma=raw.sigma)
    assert band.n_points == 1 and not band.determined and band.upper_hz == 0.0
    text = "\n".join(summary_lines(replace(amp, valid_band_raw=band)))
    f0 = f"{raw.freq_hz[0]:.4g}"
    assert f"raw not determined (only {f0} Hz passes, then unreliable point)" in text
    assert f"raw {f0}-{f0} Hz" not in text


def test_compensated_ratio_sigma_matches_scatter_between_runs(free_run):
    """The compensated / contact ratio of four runs (different noise seeds; 1 mm rms noise added on
    the displacement so that its error matters): the differences between runs over their combined
    sigma must have an rms of 1 within -15 / +20 % (66 independent complex points: the rms scatters
    by about 6 %). Dividing both forces by the noisy displacement and propagating the two ratios as
    independent gave 0.77 here: Z's error, common to both, was counted twice."""
    setup = BenchSetup.paper_shaker(2.5, nonlinear=False)
    ratios = []
    for seed in (12, 50, 51, 52):
        rng = np.random.default_rng(seed)
        records = [
            replace(
                r,
                channels={
                    **r.channels,
                    "z_base_m": r.channels["z_base_m"]
                    + 1e-3 * rng.standard_normal(r.channels["z_base_m"].size),
                },
            )
            for r in simulate_dwells(setup, SHAKER_GRID_HZ, 2e-3, seed=seed)
        ]
        ratios.append(_campaign(records, free_run, setup).nearest(2e-3).compensated_per_contact)
    z = np.concatenate(
        [np.abs(a.value - b.value) / np.hypot(a.sigma, b.sigma) for a, b in itertools.combinations(ratios, 2)]
    )
    assert 0.85 < np.sqrt(np.mean(z**2)) < 1.2


def test_free_run_with_the_plate_force_sign_flipped_is_flagged(free_run):
    """A plate force recorded with the wrong sign gives m_comp < 0: not physical, flagged with what to
    check; the right sign gives no such finding."""
    from bench.analysis.runs import analyse_free_run
    from bench.report.text import free_run_lines

    right = analyse_free_run(free_run.records)
    assert right.plate.mass_kg > 0
    assert right.findings == ()
    assert not any("not physical" in line for line in free_run_lines(right))
    flipped = [
        replace(r, channels={**r.channels, "f_plate_n": -np.asarray(r.channels["f_plate_n"])})
        for r in free_run.records
    ]
    wrong = analyse_free_run(flipped)
    assert wrong.plate.mass_kg == pytest.approx(-right.plate.mass_kg, rel=1e-9)
    flags = [line for line in free_run_lines(wrong) if line.startswith("FLAG")]
    assert len(flags) == 1
    assert "not physical" in flags[0] and "sign and units of the plate force f_plate_n" in flags[0]
