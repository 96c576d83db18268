"""Quarter-car identification from the four-post sweep: closed form against the network, recovery of
the simulator's truth for the paper's car and another one, what the data cannot determine."""

import numpy as np
import pytest

from bench.analysis.dwell import dwell_frf
from bench.analysis.plate_mass import identify_plate_mass
from bench.analysis.quarter_car_fit import (
    apparent_mass_above,
    fit_quarter_car,
    four_post_frfs,
    quarter_car_modes,
    quarter_car_response,
)
from bench.analysis.runs import analyse_four_post
from bench.analysis.shaker_models import RubberTerms, loss_element_deflection
from bench.analysis.validation import AnalysisInputError
from bench.models.benches import TyreModel, quarter_car
from bench.models.parameters import Suspension, WfsSensor, paper_tyre
from tests.analysis.conftest import OTHER_SUSPENSION, OTHER_TYRE, analyse_runs, same_tyre_campaign
from tests.documented import assert_documented

FS = 1000.0
SUSPENSION_TRUTH = {
    "unsprung_mass_above_kg": "unsprung_mass_above_kg",
    "suspension_stiffness_n_per_m": "stiffness_n_per_m",
    "suspension_damping_ns_per_m": "damping_ns_per_m",
    "body_mass_kg": "body_mass_kg",
}
#: The names docs/analysis.md quotes the errors by.
SHORT = {
    "unsprung_mass_above_kg": "m_h",
    "suspension_stiffness_n_per_m": "k_s",
    "suspension_damping_ns_per_m": "d_s",
    "body_mass_kg": "m_B",
    "body": "body mode",
    "wheel": "wheel mode",
}


@pytest.mark.parametrize("model", list(TyreModel))
@pytest.mark.parametrize(
    ("tyre", "suspension"), [(paper_tyre(1.5), Suspension()), (OTHER_TYRE, OTHER_SUSPENSION)]
)
def test_closed_form_equals_network(model, tyre, suspension):
    """Closed forms of F_wfs/Z, F_contact/Z, a_hub/Z and the apparent mass F_wfs/a_hub against the
    assembled network, 0.2-100 Hz through the body and wheel modes: 1e-9 relative (both are exact;
    the difference is rounding in solves with a 1e8 N/m sensor next to 1e4 N/m springs)."""
    f = np.geomspace(0.2, 100, 120)
    net = quarter_car(model, tyre, suspension, WfsSensor()).frequency_response(f)
    wfs, contact, accel = quarter_car_response(model, tyre, suspension, WfsSensor(), f)
    for mine, name in ((wfs, "f_wfs"), (contact, "f_contact"), (accel, "a_hub")):
        np.testing.assert_allclose(mine, net[name], rtol=1e-9, err_msg=name)
    np.testing.assert_allclose(apparent_mass_above(suspension, f), net["f_wfs"] / net["a_hub"], rtol=1e-9)


@pytest.mark.parametrize("model", list(TyreModel))
@pytest.mark.parametrize("tyre", [paper_tyre(1.5), OTHER_TYRE])
def test_loss_element_deflection_from_the_contact_force_equals_network(model, tyre):
    """The deflection of the element carrying the tyre's loss (the tyre link of Models 1/2, the upper
    sidewall of Model 3) per unit Z, from the contact force alone, against the network's own
    displacements of the car on the post, 0.2-100 Hz: 1e-9 relative (both exact)."""
    f = np.geomspace(0.2, 100, 120)
    lower_node = "z_sidewall" if model is TyreModel.WHEEL_TREAD_SIDEWALL else "z_base"
    net = quarter_car(model, tyre, Suspension(), WfsSensor()).frequency_response(
        f, outputs=("f_contact", "z_base", "z_rim", lower_node)
    )
    exact = (net[lower_node] - net["z_rim"]) / net["z_base"]
    mine = loss_element_deflection(model, tyre, f, net["f_contact"] / net["z_base"])
    np.testing.assert_allclose(mine, exact, rtol=1e-9)


def _identify(sweep, post_free_run, campaign, sensor):
    """The quarter car of the whole four-post analysis, with the tyre of the shaker campaign."""
    return analyse_four_post(
        sweep, post_free_run.records, tyre=campaign, wheel_mass_kg=campaign.wheel_mass_kg, sensor=sensor
    )


def _check_recovered(setup, fit, capsys, label):
    """Every suspension parameter within 3 % of the truth and within its 95 % half-width; the body
    and wheel modes of the identified car within 1 % of the truth's (the plant's tyre with its
    stiffness rise at each mode) and within their half-widths (1.5x them while a constant
    hysteretic loss stood for the tyre's friction on the post: k_s and the body mode were then 0.6 %
    off, about one half-width; tests/analysis/test_analysis_quarter_car_coverage.py).

    Why 3 %: the sweep's H1 is accurate to 0.9 % per bin on a linear noise-free plant (window bias of
    the swept excitation), correlated along frequency, which the stated intervals account for.
    Measured errors are below 0.3 %, so 3 % fails on any real bias (a wrong closed form, a lost
    plate-mass correction or accelerometer lag shifts them by 5-50 %)."""
    truth = setup.suspension
    # the plant's tyre stiffens with log frequency (same law and reference as RubberTerms); its
    # friction only damps the modes
    rise = RubberTerms(stiffness_rise_per_decade=setup.nonlinearity.stiffness_rise_per_decade)
    (f_b, _), (f_w, _) = quarter_car_modes(setup.model, setup.tyre, truth, setup.sensor, rise)
    errors = {}
    for name, attr in SUSPENSION_TRUTH.items():
        true = getattr(truth, attr)
        errors[name] = fit.values[name] / true - 1
        assert abs(fit.values[name] - true) <= 0.03 * true, name
        assert abs(fit.values[name] - true) <= fit.ci95[name], name
    for found, ci, true, name in (
        (fit.body_frequency_hz, fit.body_frequency_ci95_hz, f_b, "body"),
        (fit.wheel_frequency_hz, fit.wheel_frequency_ci95_hz, f_w, "wheel"),
    ):
        errors[name] = found / true - 1
        assert abs(found - true) <= 0.01 * true, name
        assert abs(found - true) <= ci, name
    assert fit.converged and fit.reduced_chi2 < 30
    assert not set(fit.undetermined) & set(SUSPENSION_TRUTH)
    text = f"{label}: " + ", ".join(f"{SHORT[k]} {100 * v:+.2f} %" for k, v in errors.items())
    with capsys.disabled():
        print(f"\n  quarter car {text}")
    assert_documented("docs/analysis.md", text)  # seeded


def test_paper_quarter_car_recovered(four_post_analysis, capsys):
    """The paper's corner (non-linear tyre, sensor noise, Model 2 or 3 truth) with the tyre from the
    shaker identification of the same tyre at the same pressure and 2 mm, as a lab would. (Given the
    Model 2 tyre instead, the Model 3 car fits with a reduced chi^2 above 1000: the mismatch shows.)"""
    setup, result = four_post_analysis
    fit = result.quarter_car
    _check_recovered(setup, fit, capsys, f"paper's car, Model {int(setup.model)} tyre")
    frfs = result.frfs
    # the post displacement is the cleanest channel: H1 for every response, compensated forces included
    assert all(s.estimator == "h1" for s in frfs.sweeps.values())
    assert fit.band_hz[0] > 1.5 and fit.band_hz[1] < 30  # flanks of the sweep are not used
    assert any("shaker" in g for g in fit.taken_as_given)
    # the mass-production accelerometer's lag: 600 Hz second-order Butterworth, sqrt(2)/(2 pi 600) s
    assert fit.accelerometer_delay_s == pytest.approx(np.sqrt(2) / (2 * np.pi * 600), rel=0.15)


def test_other_quarter_car_recovered(
    four_post_other_car, four_post_free_run, shaker_other_tyre_nonlinear, free_run, capsys
):
    """A car unlike the paper's (other tyre, hub carrier, body, spring and damper) on the same post."""
    setup, sweep = four_post_other_car
    campaign = analyse_runs([shaker_other_tyre_nonlinear], free_run)
    fit = _identify(sweep, four_post_free_run, campaign, setup.sensor).quarter_car
    _check_recovered(setup, fit, capsys, "another car")


def test_band_above_the_wheel_mode_leaves_body_and_spring_undetermined(
    four_post, four_post_free_run, request
):
    """Data from 15 Hz up (10x the 1.6 Hz body mode, above the wheel mode): the body and spring enter
    only through ``K m_B / (K - m_B w^2) ~ -(k_s + j w d_s) / w^2 - ...``, where k_s is a 2 %
    correction to the hub's 25 kg and m_B a smaller one. Both must be reported as not determined
    (measured: determined, within 35 %, from a 12 Hz start), while m_h and d_s stay determined."""
    setup, sweep = four_post
    tyre_fit = same_tyre_campaign(setup, request).nearest(sweep.amplitude_m).identification.best_fit
    post = identify_plate_mass(dwell_frf(four_post_free_run.fits, "f_plate_n", "z_base_m"))
    frfs = four_post_frfs(sweep.channels, FS, post, band_hz=(15.0, 30.0))
    fit = fit_quarter_car(
        frfs,
        model=tyre_fit.model,
        tyre=tyre_fit.tyre,
        sensor=setup.sensor,
        amplitude_m=sweep.amplitude_m,
        rubber=tyre_fit.rubber,
    )
    assert {"body_mass_kg", "suspension_stiffness_n_per_m"} <= set(fit.undetermined)
    assert not {"unsprung_mass_above_kg", "suspension_damping_ns_per_m"} & set(fit.undetermined)


def test_garbage_in(four_post, four_post_free_run):
    setup, sweep = four_post
    rec = sweep.channels
    post = identify_plate_mass(dwell_frf(four_post_free_run.fits, "f_plate_n", "z_base_m"))
    with pytest.raises(AnalysisInputError, match="no channel"):
        four_post_frfs({k: v for k, v in rec.items() if k != "a_hub_m_s2"}, FS, post, band_hz=(0.3, 30.0))
    short = {k: v[:3000] for k, v in rec.items()}
    with pytest.raises(AnalysisInputError):
        frfs = four_post_frfs(short, FS, post, band_hz=(0.3, 30.0))
        fit_quarter_car(
            frfs,
            model=TyreModel.WHEEL_TREAD,
            tyre=setup.tyre,
            sensor=setup.sensor,
            amplitude_m=sweep.amplitude_m,
        )
    broken = dict(rec)
    broken["fz_wfs_n"] = replace_nan(rec["fz_wfs_n"])
    with pytest.raises(AnalysisInputError, match="non-finite"):
        four_post_frfs(broken, FS, post, band_hz=(0.3, 30.0))


def replace_nan(x):
    y = x.copy()
    y[500] = np.nan
    return y
