"""Identification on simulated shaker campaigns recovers the simulator's truth, for the paper's tyre
and for another one, linear and non-linear."""

import pytest

from bench.analysis.dwell import dwell_frf
from bench.analysis.plate_mass import identify_plate_mass, shaker_frfs
from bench.analysis.tyre_fit import amplitude_dependence, identify_shaker, tread_resonance_hz
from bench.models.benches import TyreModel
from tests.documented import assert_documented


def _identify(run, free_run):
    plate = identify_plate_mass(dwell_frf(free_run.fits, "f_plate_n", "z_base_m"))
    frfs = shaker_frfs(run.fits, plate)
    setup = run.plant.setup
    ident = identify_shaker(
        frfs.wfs_per_z, frfs.contact_per_z, wheel_mass_kg=setup.tyre.wheel_mass_kg, sensor=setup.sensor
    )
    return frfs, ident


@pytest.mark.parametrize("run_name", ["shaker_linear", "shaker_other_tyre"])
def test_linear_tyre_recovered(run_name, free_run, request):
    """Issue tolerances: k 2 %, tread mass 3 %, damping 15 %. The dwells are accurate to ~1e-4, so the
    estimates land far inside; Model 2 (the truth) must win by BIC, Model 1 must fail on the ratio,
    and Model 3's sidewall must be reported as not determined (the data carries no trace of it)."""
    run = request.getfixturevalue(run_name)
    _, ident = _identify(run, free_run)
    truth = run.plant.setup.tyre
    assert ident.best is TyreModel.WHEEL_TREAD
    assert not ident.frequency_dependent_stiffness
    fit = ident.best_fit
    assert fit.tyre.stiffness_n_per_m == pytest.approx(truth.stiffness_n_per_m, rel=0.02)
    assert fit.tyre.tread_mass_kg == pytest.approx(truth.tread_mass_kg, rel=0.03)
    assert fit.tyre.damping_ns_per_m == pytest.approx(truth.damping_ns_per_m, rel=0.15)
    assert fit.undetermined == ()
    assert ident.fits[TyreModel.WHEEL].ratio_relative_rms > 0.3
    assert "sidewall_mass_kg" in ident.fits[TyreModel.WHEEL_TREAD_SIDEWALL].undetermined


def test_nonlinear_tyre_per_amplitude(free_run, shaker_nonlinear):
    """The simulator's rubber: stiffness rising with log frequency and friction damping falling with
    amplitude. Per amplitude, the identified stiffness and equivalent damping at the tread resonance
    must match the plant's linearised tyre at that operating point (2 % and 15 %), the stiffness
    rise must be detected, and the damping must fall from 1 to 5 mm while k stays put."""
    per_amp = {}
    for amp, run in shaker_nonlinear.items():
        frfs, ident = _identify(run, free_run)
        assert ident.frequency_dependent_stiffness and ident.best is TyreModel.WHEEL_TREAD
        fit = ident.best_fit
        f_res = tread_resonance_hz(fit)
        truth = run.plant.setup.linear_tyre(f_res, amp)
        k_fit = fit.tyre.stiffness_n_per_m * float(fit.rubber.stiffness_factor(f_res))
        assert k_fit == pytest.approx(truth.stiffness_n_per_m, rel=0.02)
        d_fit = float(fit.rubber.equivalent_damping_ns_per_m(fit.tyre, f_res))
        assert d_fit == pytest.approx(truth.damping_ns_per_m, rel=0.15)
        assert fit.tyre.tread_mass_kg == pytest.approx(run.plant.setup.tyre.tread_mass_kg, rel=0.03)
        per_amp[amp] = (frfs.wfs_per_z, frfs.contact_per_z)
    setup = next(iter(shaker_nonlinear.values())).plant.setup
    dep = amplitude_dependence(
        per_amp, wheel_mass_kg=29.0, sensor=setup.sensor, stiffness_rise=True, hysteretic=True
    )
    assert abs(dep.stiffness_change).max() < 0.01
    assert dep.damping_change[1] < -0.05 and dep.damping_change[2] < dep.damping_change[1]


def test_the_readme_quotes_the_identification_errors(free_run, shaker_linear, shaker_other_tyre):
    """The largest error of k, m_T and d over the paper's tyre and the other one (linear, 2 mm
    dwells, seeded), and of m_comp from the free run: what README.md quotes (printed with ``-s``)."""
    errors = {"k": 0.0, "m_T": 0.0, "d": 0.0}
    for run in (shaker_linear, shaker_other_tyre):
        _, ident = _identify(run, free_run)
        fit, truth = ident.best_fit.tyre, run.plant.setup.tyre
        for name, attribute in (
            ("k", "stiffness_n_per_m"),
            ("m_T", "tread_mass_kg"),
            ("d", "damping_ns_per_m"),
        ):
            error = abs(getattr(fit, attribute) / getattr(truth, attribute) - 1)
            errors[name] = max(errors[name], error)
    plate = identify_plate_mass(dwell_frf(free_run.fits, "f_plate_n", "z_base_m"))
    m_comp = abs(plate.mass_kg / free_run.plant.setup.rig.plate_mass_kg - 1)
    assert errors["k"] < 0.02 and errors["m_T"] < 0.03 and errors["d"] < 0.15
    text = (
        f"identification recovers tyre stiffness, tread mass and damping to {100 * errors['k']:.2g},"
        f" {100 * errors['m_T']:.2g} and {100 * errors['d']:.2g} % and m_comp to {100 * m_comp:.2g} %"
    )
    print(f"\n  {text}")
    assert_documented("README.md", text)
