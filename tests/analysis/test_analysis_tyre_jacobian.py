"""The exact derivatives of the shaker responses and of the tyre fit's misfit equal central
differences, and the fit's intervals equal those of a central-difference Jacobian."""

from dataclasses import replace

import numpy as np
import pytest

from bench.analysis.frf import Frf
from bench.analysis.lsq import Z95, weighted_fit
from bench.analysis.plate_mass import ShakerErrors
from bench.analysis.shaker_models import (
    MODEL_PARAMETERS,
    RubberTerms,
    shaker_response,
    shaker_response_derivatives,
)
from bench.analysis.tyre_fit import (
    HYST,
    PLATE_MASS_OFFSET,
    RATE,
    _data,
    _Misfit,
    fit_tyre_model,
)
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor

FREQ = np.geomspace(0.5, 70.0, 24)
SENSOR = WfsSensor(mass_kg=4.0, eigenfrequency_hz=1900.0, damping_ratio=0.03)
RUBBER_NAMES = ("stiffness_rise_per_decade", "hysteretic_damping_n_per_m")
#: Relative step of the central differences: truncation ~ step^2, rounding ~ 1e-16 / step; the
#: intervals of a fit whose J has singular values ~1e-8 of the largest need the smaller rounding error.
STEP = 1e-6
INTERVAL_STEP = 1e-4


def _random_point(rng: np.random.Generator) -> tuple[Tyre, RubberTerms]:
    """A tyre and rubber terms drawn over the ranges the fits visit (sidewall mode in the band
    or above it)."""
    k = rng.uniform(1.5e5, 4.5e5)
    tyre = Tyre(
        stiffness_n_per_m=k,
        damping_ns_per_m=rng.uniform(20.0, 300.0),
        wheel_mass_kg=rng.uniform(20.0, 35.0),
        tread_mass_kg=rng.uniform(2.0, 8.0),
        sidewall_mass_kg=rng.uniform(0.3, 3.0),
        sidewall_lower_stiffness_n_per_m=rng.uniform(1e5, 1e7),
        sidewall_upper_stiffness_n_per_m=rng.uniform(1e4, 1e6),
    )
    return tyre, RubberTerms(rng.uniform(-0.05, 0.1), rng.uniform(0.0, 0.03) * k)


def _central(fun, value: float, step: float = STEP):
    """Central difference of ``fun`` at ``value`` with a relative step."""
    h = step * abs(value)
    return (fun(value + h) - fun(value - h)) / (2 * h)


@pytest.mark.parametrize("model", list(TyreModel))
@pytest.mark.parametrize("seed", range(5))
def test_response_derivatives_equal_central_differences(model, seed):
    tyre, rubber = _random_point(np.random.default_rng(seed))
    names = MODEL_PARAMETERS[model] + RUBBER_NAMES
    wfs, contact, d_wfs, d_contact = shaker_response_derivatives(
        model, tyre, SENSOR, FREQ, rubber, names=names
    )
    np.testing.assert_allclose(np.stack([wfs, contact]), shaker_response(model, tyre, SENSOR, FREQ, rubber))
    for i, name in enumerate(names):
        on_rubber = name in RUBBER_NAMES

        def response(value, name=name, on_rubber=on_rubber):
            if on_rubber:
                return np.stack(shaker_response(model, tyre, SENSOR, FREQ, replace(rubber, **{name: value})))
            return np.stack(shaker_response(model, replace(tyre, **{name: value}), SENSOR, FREQ, rubber))

        numeric = _central(response, getattr(rubber if on_rubber else tyre, name))
        exact = np.stack([d_wfs[i], d_contact[i]])
        scale = np.max(np.abs(numeric), axis=1, keepdims=True)
        assert np.max(np.abs(exact - numeric) / scale) < 1e-6, name


def test_a_parameter_the_model_lacks_is_refused():
    tyre, rubber = _random_point(np.random.default_rng(0))
    with pytest.raises(ValueError, match="sidewall_mass_kg"):
        shaker_response_derivatives(
            TyreModel.WHEEL_TREAD, tyre, SENSOR, FREQ, rubber, names=("sidewall_mass_kg",)
        )


def _shaker_data(model: TyreModel, tyre: Tyre, rubber: RubberTerms, *, shared_errors: bool, seed: int):
    """Noisy F_wfs/Z and F_contact/Z of the model (0.2 % points), and their shared errors."""
    rng = np.random.default_rng(seed)
    frfs = []
    for h in shaker_response(model, tyre, SENSOR, FREQ, rubber):
        sigma = 2e-3 * np.abs(h)
        noise = sigma / np.sqrt(2) * (rng.standard_normal(h.size) + 1j * rng.standard_normal(h.size))
        frfs.append(Frf(FREQ, h + noise, sigma, np.ones(h.size, bool), "out", "z_base"))
    errors = None
    if shared_errors:
        errors = ShakerErrors(frfs[0].sigma, frfs[1].sigma, np.full(FREQ.size, 1e-3), 12.0, 3e-4)
    return frfs, errors


def _values(names, tyre: Tyre, rubber: RubberTerms, offset_kg: float) -> dict[str, float]:
    values = {n: getattr(tyre, n) for n in names if n in MODEL_PARAMETERS[TyreModel.WHEEL_TREAD_SIDEWALL]}
    values |= {n: getattr(rubber, n) for n in names if n in (RATE, HYST)}
    if PLATE_MASS_OFFSET in names:
        values[PLATE_MASS_OFFSET] = offset_kg
    return values


@pytest.mark.parametrize("model", list(TyreModel))
@pytest.mark.parametrize(("rate", "hyst"), [(False, False), (True, False), (False, True), (True, True)])
@pytest.mark.parametrize("shared_errors", [False, True])
def test_misfit_jacobian_equals_central_differences(model, rate, hyst, shared_errors):
    """Every model variant, with and without the plate-mass offset, at a point off the data."""
    rng = np.random.default_rng(7)
    truth, rubber = _random_point(rng)
    (wfs, contact), errors = _shaker_data(model, truth, rubber, shared_errors=shared_errors, seed=3)
    misfit = _Misfit(model, _data(wfs, contact, errors), SENSOR, truth.wheel_mass_kg)
    point, point_rubber = _random_point(rng)
    point = replace(point, wheel_mass_kg=truth.wheel_mass_kg)
    names = MODEL_PARAMETERS[model] + ((RATE,) if rate else ()) + ((HYST,) if hyst else ())
    names += (PLATE_MASS_OFFSET,) if shared_errors else ()
    values = _values(names, point, point_rubber, offset_kg=2e-4)
    exact = misfit.jacobian(values)
    assert exact.shape == (misfit.residuals(values).size, len(names))
    for j, name in enumerate(names):
        numeric = _central(lambda v, name=name: misfit.residuals({**values, name: v}), values[name])
        assert np.max(np.abs(exact[:, j] - numeric)) < 1e-6 * np.max(np.abs(numeric)), name


def _central_ci95(misfit: _Misfit, values: dict[str, float], sigma_offset_kg: float) -> np.ndarray:
    """95 % half-widths ``1.96 sqrt(diag(s^2 (J^T J)^-1))`` from a central-difference Jacobian, in
    units of each value (the fit's own scaling), where ``J^T J`` stays within double precision."""
    columns = [
        _central(lambda v, n=n: misfit.residuals({**values, n: v}), values[n], INTERVAL_STEP) for n in values
    ]
    jac = np.stack(columns, axis=1)
    residuals = misfit.residuals(values)
    scale = np.array([abs(v) or sigma_offset_kg for v in values.values()])
    _, sv, vt = np.linalg.svd(jac * scale, full_matrices=False)
    variance = np.sum((vt / sv[:, None]) ** 2, axis=0) * scale**2 * (residuals @ residuals)
    return Z95 * np.sqrt(variance / (residuals.size - len(values))), sv


def test_model2_fit_equals_the_finite_difference_fit():
    """The solver reaches the same values as with scipy's forward differences (within 1e-4 of their
    intervals), and the intervals equal those of central differences (J's smallest singular value
    is ~1e-8 of its largest here: forward differences err on the intervals by up to 0.5 %)."""
    truth = Tyre(stiffness_n_per_m=280e3, damping_ns_per_m=110.0, tread_mass_kg=5.2)
    rubber = RubberTerms(0.03, 4e3)
    (wfs, contact), errors = _shaker_data(TyreModel.WHEEL_TREAD, truth, rubber, shared_errors=True, seed=5)
    fit = fit_tyre_model(
        TyreModel.WHEEL_TREAD,
        wfs,
        contact,
        wheel_mass_kg=29.0,
        sensor=SENSOR,
        stiffness_rise=True,
        hysteretic=True,
        errors=errors,
    )
    misfit = _Misfit(TyreModel.WHEEL_TREAD, _data(wfs, contact, errors), SENSOR, 29.0)
    start = fit.lsq.values
    bounds = {n: (-np.inf, np.inf) for n in start}
    by_differences = weighted_fit(misfit.residuals, start, bounds)
    central, _ = _central_ci95(misfit, fit.lsq.values, errors.plate_mass_sigma_kg)
    for i, name in enumerate(start):
        moved = abs(fit.lsq.values[name] - by_differences.values[name])
        assert moved < 1e-4 * fit.lsq.ci95[name], name
        assert fit.lsq.ci95[name] == pytest.approx(central[i], rel=1e-6), name


def test_model3_intervals_equal_those_of_central_differences():
    """Model 3 on Model 2 data: a flat valley (the sidewall is not determined) where the smallest
    singular values of J are ~1e-8 of the largest, which forward differences miss by up to a factor
    2; the exact J and central differences agree on every interval."""
    truth = Tyre(stiffness_n_per_m=250e3, damping_ns_per_m=80.0, tread_mass_kg=6.0)
    rubber = RubberTerms(0.03, 2.5e3)
    (wfs, contact), errors = _shaker_data(TyreModel.WHEEL_TREAD, truth, rubber, shared_errors=True, seed=2)
    model = TyreModel.WHEEL_TREAD_SIDEWALL
    kw = {"wheel_mass_kg": 29.0, "sensor": SENSOR, "stiffness_rise": True, "hysteretic": True}
    fit = fit_tyre_model(model, wfs, contact, errors=errors, **kw)
    assert {"sidewall_mass_kg", "sidewall_lower_stiffness_n_per_m"} <= set(fit.undetermined)
    misfit = _Misfit(model, _data(wfs, contact, errors), SENSOR, 29.0)
    central, sv = _central_ci95(misfit, fit.lsq.values, errors.plate_mass_sigma_kg)
    assert sv[-1] < 1e-6 * sv[0]
    for i, name in enumerate(fit.lsq.values):
        assert fit.lsq.ci95[name] == pytest.approx(central[i], rel=2e-3), name
