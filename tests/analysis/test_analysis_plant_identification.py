"""Identification on simulated shaker campaigns recovers the simulator's truth, for the paper's tyre
and for another one, linear and non-linear."""

import pytest

from bench.analysis.dwell import dwell_frf
from bench.analysis.plate_mass import identify_plate_mass, shaker_frfs
from bench.analysis.tyre_fit import amplitude_dependence, identify_shaker, tread_resonance_hz
from bench.models.benches import TyreModel


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
