"""The quarter car above the sensor, identified from a four-post sweep (paper, 2.4 and 3.2).

Data: the sweep FRFs over the post displacement ``Z`` (the cleanest channel, so H1 is unbiased):
``F_wfs / Z``, ``F_contact / Z`` (post load cell, plate-mass corrected: ``F_plate / Z + m_comp w^2``)
and ``a_hub / Z``. Their ratio ``F_wfs / a_hub`` is the *apparent mass above the sensor* (the
hub-acceleration relation); as a ratio of two H1 estimates over the clean ``Z`` it is not biased by
the noise of either channel, unlike a direct estimate against the noisy accelerometer.

Model (closed form, tested equal to :func:`bench.models.benches.quarter_car`). Below the sensor the
tyre and wheel are linear in ``Z`` and the hub displacement ``z_h``
(:mod:`bench.analysis.shaker_models`)::

    F_wfs = P Z + Q z_h,   F_contact = R Z + S z_h

Above it the hub mass ``m_h`` (unsprung mass above the sensing element) carries the body ``m_B`` on
the suspension ``K = k_s + j w d_s``::

    F_wfs = U z_h,   U = -m_h w^2 - K m_B w^2 / (K - m_B w^2)

so ``z_h = P Z / (U - Q)``, ``F_wfs / Z = U P / (U - Q)``, ``F_contact / Z = R + S P / (U - Q)``,
``a_hub / Z = -w^2 P / (U - Q)`` and ``F_wfs / a_hub = -U / w^2 = m_h + K m_B / (K - m_B w^2)``:
``m_h + m_B`` well below the body mode, ``m_h`` well above it. The hub accelerometer's lag (a
mass-production sensor's low-pass) is a fitted delay ``tau``: ``a_meas = a_hub exp(-j w tau)``.

Fit: :func:`bench.analysis.lsq.weighted_fit` on the real and imaginary parts of all three FRFs over
their reliable bins, weighted by the bins' uncertainties (floored at 0.1 %). Fitted: the suspension
(``m_h``, ``k_s``, ``d_s``, ``m_B``), ``tau``, and the tyre's friction force on the post
(:class:`PostFriction`). Rubber friction damps more the less the rubber deflects (its describing
function at a deflection amplitude ``X`` is the hysteretic loss ``4 F_c / (pi X)``), and on the post
the tyre deflects several times less at the body mode than at the wheel mode, and less than on the
shaker: one constant hysteretic loss fitted the wheel mode and under-damped the body mode, which
k_s and m_B made up (k_s 0.7 % low, its interval covering the truth in 2 of 20 seeds). So the loss
at each bin is the friction force over the deflection the measured contact force gives the
element that carries it (:func:`~bench.analysis.shaker_models.loss_element_deflection`). Everything else
about the tyre is taken from the shaker identification at the same pressure, as a lab would:
fitting the tyre's stiffness and tread mass on the post as well was tried on the simulated plant
and traded them against the body mass (tread +12 %, body +5 %) with intervals that did not cover
the error. The wheel mass below the sensor (weighed), the sensor (hammer test, or as stated) and Model 3's
sidewall are not identifiable from this data either; :attr:`QuarterCarFit.taken_as_given` lists
them. Neighbouring Welch bins are correlated (the Hann window's equivalent noise bandwidth is 1.5
bins) and a model error makes neighbouring residuals alike, so the covariance is inflated by
``(1 + rho) / (1 - rho)`` from the residuals' lag-1 correlation, at least by 1.5.

Eigenfrequencies: body and wheel modes of the identified quarter car (undamped natural frequency
``|lambda| / 2 pi`` and damping ratio ``-Re(lambda) / |lambda|`` of the two lowest modes, the post
held still), with the rubber terms evaluated at each mode's own frequency; 95 % intervals by
first-order propagation of the fit's covariance.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from bench.analysis.frf import Frf, phasor_ratio
from bench.analysis.lsq import (
    Z95,
    FitStatistics,
    LsqResult,
    correlated_residual_factor,
    relative_resolution,
    weighted_fit,
)
from bench.analysis.plate_mass import PlateMass
from bench.analysis.shaker_models import (
    LINEAR,
    RubberTerms,
    hub_driven_response,
    loss_element_deflection,
    shaker_response,
)
from bench.analysis.sweep import SweepFrf, sweep_frfs, sweep_ratio
from bench.analysis.validation import AnalysisInputError
from bench.models.benches import TyreModel, quarter_car
from bench.models.parameters import Suspension, Tyre, WfsSensor

SUSPENSION_PARAMETERS = (
    "unsprung_mass_above_kg",
    "suspension_stiffness_n_per_m",
    "suspension_damping_ns_per_m",
    "body_mass_kg",
)
DELAY = "accelerometer_delay_s"
FRICTION = "tyre_friction_force_n"
#: Equivalent noise bandwidth of the Hann window in bins: neighbouring Welch bins share information.
HANN_ENBW_BINS = 1.5
#: Relative floor on the bin uncertainties (model form), so that no bin gets an extreme weight.
RELATIVE_SIGMA_FLOOR = 1e-3
#: A delay is 'determined' when known to 0.1 ms (1 degree of phase at 30 Hz) or half its value.
DELAY_RESOLUTION_S = 1e-4


def apparent_mass_above(suspension: Suspension, freq_hz: np.ndarray) -> np.ndarray:
    """``F_wfs / a_hub = m_h + K m_B / (K - m_B w^2)``, kg (see the module docstring)."""
    w = 2 * np.pi * np.asarray(freq_hz, dtype=float)
    k = suspension.stiffness_n_per_m + 1j * w * suspension.damping_ns_per_m
    m_b = suspension.body_mass_kg
    return suspension.unsprung_mass_above_kg + k * m_b / (k - m_b * w**2)


def quarter_car_response(
    model: TyreModel,
    tyre: Tyre,
    suspension: Suspension,
    sensor: WfsSensor,
    freq_hz: np.ndarray,
    *,
    rubber: RubberTerms = LINEAR,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F_wfs / Z, F_contact / Z, a_hub / Z)`` of a quarter car on a post (N/m, N/m, 1/s^2)."""
    w = 2 * np.pi * np.asarray(freq_hz, dtype=float)
    p, r = shaker_response(model, tyre, sensor, freq_hz, rubber)
    q, s = hub_driven_response(model, tyre, sensor, freq_hz, rubber)
    u = -(w**2) * apparent_mass_above(suspension, freq_hz)
    z_hub = p / (u - q)
    return u * z_hub, r + s * z_hub, -(w**2) * z_hub


@dataclass(frozen=True)
class FourPostFrfs:
    """Sweep FRFs of a four-post run over the post displacement: ``wfs_per_z`` (N/m),
    ``contact_per_z`` (N/m, plate-mass corrected) and ``accel_per_z`` (1/s^2), each with its
    :class:`~bench.analysis.sweep.SweepFrf` details (estimator, coherence, averages).
    ``per_contact``: every force response (``f_wfs`` and the extra responses) over the contact
    force at the same bins, by :func:`~bench.analysis.sweep.sweep_ratio` (not the ratio of two
    Welch FRFs), with m_comp's uncertainty propagated; usable where both FRFs over ``Z`` are
    reliable or reliable but for the sweep's flank (:attr:`SweepFrf.ratio_usable`)."""

    wfs_per_z: Frf
    contact_per_z: Frf
    accel_per_z: Frf
    sweeps: dict[str, SweepFrf]
    per_contact: dict[str, Frf]

    def apparent_mass_above(self) -> Frf:
        """The hub-acceleration relation ``F_wfs / a_hub`` (kg), reliable where both FRFs are."""
        h, s = phasor_ratio(
            self.wfs_per_z.value, self.wfs_per_z.sigma, self.accel_per_z.value, self.accel_per_z.sigma
        )
        reliable = self.wfs_per_z.reliable & self.accel_per_z.reliable
        return Frf(self.wfs_per_z.freq_hz, h, s, reliable, "f_wfs", "a_hub")


def four_post_frfs(
    record: Mapping[str, np.ndarray],
    fs_hz: float,
    plate: PlateMass,
    *,
    band_hz: tuple[float, float],
    displacement: str = "z_base_m",
    post_force: str = "f_plate_n",
    wfs: str = "fz_wfs_n",
    hub_acceleration: str = "a_hub_m_s2",
    nperseg: int | None = None,
    extra_responses: Mapping[str, np.ndarray] | None = None,
    gaps_s: Sequence[tuple[float, float]] = (),
) -> FourPostFrfs:
    """The FRFs of a four-post sweep ``record`` (channels by name); the post's m_comp corrects the
    load cell (``F_contact / Z = F_plate / Z + m_comp w^2``, its uncertainty propagated).

    ``extra_responses`` (compensated forces, as long as the record) are estimated over ``Z`` with
    the same segments, so their FRFs share the bins of the others; they are in ``sweeps``. They are
    H1 estimates: a filtered force (the model compensator rolls off above its band) has no noise
    left above the sweep, so the automatic rule would take its noise floor for zero and pick H2,
    while the post displacement is the cleanest channel (the rule picks H1 for every raw channel).
    ``gaps_s``: stretches (s) where frames were lost, which the record only bridges: the bins swept
    there are left out (:func:`~bench.analysis.sweep.sweep_frfs`)."""
    for name in (displacement, post_force, wfs, hub_acceleration):
        if name not in record:
            raise AnalysisInputError(f"the four-post record has no channel {name!r}")
    clash = {"f_plate", "f_wfs", "a_hub", "z_base"} & set(extra_responses or {})
    if clash:
        raise AnalysisInputError(f"extra responses may not be named {sorted(clash)}")
    kw = {"band_hz": band_hz, "reference_name": "z_base", "nperseg": nperseg, "gaps_s": gaps_s}
    res = sweep_frfs(
        record[displacement],
        {"f_plate": record[post_force], "f_wfs": record[wfs], "a_hub": record[hub_acceleration]},
        fs_hz,
        **kw,
    )
    if extra_responses:
        res.update(sweep_frfs(record[displacement], extra_responses, fs_hz, estimator="h1", **kw))
    plate_frf = res["f_plate"].frf
    w2 = (2 * np.pi * plate_frf.freq_hz) ** 2
    contact = Frf(
        plate_frf.freq_hz,
        plate_frf.value + plate.mass_kg * w2,
        np.hypot(plate_frf.sigma, w2 * plate.sigma_kg),
        plate_frf.reliable,
        "f_contact",
        "z_base",
    )
    forces = {"f_wfs": record[wfs], **(extra_responses or {})}
    ratios = _per_contact(
        record[displacement], record[post_force], forces, fs_hz=fs_hz, plate=plate, sweeps=res
    )
    return FourPostFrfs(res["f_wfs"].frf, contact, res["a_hub"].frf, res, ratios)


def _per_contact(
    z: np.ndarray,
    f_plate: np.ndarray,
    forces: Mapping[str, np.ndarray],
    *,
    fs_hz: float,
    plate: PlateMass,
    sweeps: Mapping[str, SweepFrf],
) -> dict[str, Frf]:
    """Each force over ``F_contact = F_plate + m_comp z''`` (see :attr:`FourPostFrfs.per_contact`).
    m_comp's error moves the ratio by ``H w^2 sigma_m / (F_contact / Z)``."""
    plate_frf = sweeps["f_plate"]
    f = plate_frf.frf.freq_hz
    w2 = (2 * np.pi * f) ** 2
    bins = {"freq_hz": f, "resolution_hz": plate_frf.resolution_hz}
    plate_per_z, _ = sweep_ratio(z, f_plate, z, fs_hz, **bins)

    def plate_term(freq_hz: np.ndarray) -> np.ndarray:
        return plate.mass_kg * (2 * np.pi * freq_hz) ** 2

    contact_per_z = plate_per_z + plate.mass_kg * w2
    out = {}
    for name, force in forces.items():
        h, noise = sweep_ratio(z, force, f_plate, fs_hz, **bins, denominator_per_reference=plate_term)
        sigma = np.hypot(noise, np.abs(h) * w2 * plate.sigma_kg / np.abs(contact_per_z))
        usable = sweeps[name].ratio_usable & plate_frf.ratio_usable
        out[name] = Frf(f, h, sigma, usable, name, "f_contact")
    return out


@dataclass(frozen=True)
class QuarterCarFit(FitStatistics):
    """The quarter car identified from a four-post run.

    ``suspension`` (what stands above the sensor), ``tyre`` and ``rubber`` (given: the shaker's),
    ``friction`` (the tyre's loss on the post, its friction force fitted there) and
    ``accelerometer_delay_s``; ``lsq``: the least-squares result, whose ``values``/``ci95`` (every
    fitted parameter and its 95 % half-width by name with units), ``undetermined`` (fitted
    parameters the data does not determine: do not use their numbers), ``chi2``, ``n_residuals``,
    ``n_parameters``, ``converged`` and ``reduced_chi2`` are properties of the fit too;
    ``taken_as_given``: what this data cannot identify and was taken from elsewhere. Modes:
    ``body_frequency_hz``/``wheel_frequency_hz`` (undamped, with 95 % half-widths) and their
    damping ratios. ``band_hz``: lowest and highest reliable bin used.
    """

    model: TyreModel
    tyre: Tyre
    rubber: RubberTerms
    friction: PostFriction
    suspension: Suspension
    accelerometer_delay_s: float
    lsq: LsqResult
    taken_as_given: tuple[str, ...]
    body_frequency_hz: float
    body_frequency_ci95_hz: float
    body_damping_ratio: float
    wheel_frequency_hz: float
    wheel_frequency_ci95_hz: float
    wheel_damping_ratio: float
    band_hz: tuple[float, float]

    @property
    def values(self) -> dict[str, float]:
        return self.lsq.values

    @property
    def ci95(self) -> dict[str, float]:
        return self.lsq.ci95

    @property
    def undetermined(self) -> tuple[str, ...]:
        return self.lsq.undetermined


def quarter_car_modes(
    model: TyreModel,
    tyre: Tyre,
    suspension: Suspension,
    sensor: WfsSensor,
    rubber: RubberTerms = LINEAR,
    *,
    loss_n_per_m: Callable[[float], float] | None = None,
) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((f_body_hz, zeta_body), (f_wheel_hz, zeta_wheel))``: the two lowest modes of the quarter
    car with the post held still, each with the tyre's rubber terms taken at its own frequency
    (three fixed-point passes: the stiffness rise changes a mode by well under 1 %);
    ``loss_n_per_m``: the tyre's hysteretic loss at a frequency, in place of the rubber's constant
    one (:meth:`PostFriction.loss_n_per_m`)."""
    modes = []
    for index in (0, 1):
        f_mode = 10.0
        for _ in range(3):
            at_mode = (
                rubber
                if loss_n_per_m is None
                else replace(rubber, hysteretic_damping_n_per_m=loss_n_per_m(f_mode))
            )
            local = replace(
                tyre,
                stiffness_n_per_m=tyre.stiffness_n_per_m * float(at_mode.stiffness_factor(f_mode)),
                damping_ns_per_m=float(at_mode.equivalent_damping_ns_per_m(tyre, f_mode)),
            )
            a = quarter_car(model, local, suspension, sensor).state_space(outputs=()).A
            lam = np.linalg.eigvals(a)
            lam = lam[lam.imag > 0]
            lam = lam[np.argsort(np.abs(lam))][index]
            f_mode = float(np.abs(lam) / (2 * np.pi))
        modes.append((f_mode, float(-lam.real / np.abs(lam))))
    return modes[0], modes[1]


@dataclass(frozen=True)
class PostFriction:
    """The tyre's loss on the post as rubber friction: a friction force ``friction_force_n`` whose
    describing function at a deflection amplitude ``X`` is the hysteretic loss ``4 F / (pi X)``
    (N/m), the law of the simulated tyre and of dry friction. ``X`` at each frequency is the
    sweep's displacement amplitude ``amplitude_m`` times the deflection of the loss element per
    unit ``Z``, ``deflection_per_z`` at the bins ``freq_hz`` (its magnitude, from the measured
    contact force: :func:`~bench.analysis.shaker_models.loss_element_deflection`), interpolated
    between them and held beyond them. On the shaker the element deflects by about the plate's
    amplitude at every frequency and this is the shaker fit's constant hysteretic loss; on the post
    the car moves with the tyre at low frequency, the deflection grows several-fold towards the
    wheel mode and the loss falls as it grows."""

    friction_force_n: float
    amplitude_m: float
    freq_hz: np.ndarray
    deflection_per_z: np.ndarray

    def deflection_m(self, freq_hz: np.ndarray | float) -> np.ndarray:
        """The loss element's deflection amplitude ``X`` (m) at ``freq_hz``."""
        return self.amplitude_m * np.interp(freq_hz, self.freq_hz, self.deflection_per_z)

    def loss_n_per_m(self, freq_hz: np.ndarray | float) -> np.ndarray:
        """The hysteretic loss ``4 F / (pi X)`` (N/m) at ``freq_hz``."""
        return 4 * self.friction_force_n / (np.pi * self.deflection_m(freq_hz))


@dataclass(frozen=True)
class _PostData:
    freq_hz: np.ndarray
    h: np.ndarray  # stacked [wfs; contact; accel]
    sigma: np.ndarray


def _post_data(frfs: FourPostFrfs) -> _PostData:
    parts = (frfs.wfs_per_z, frfs.contact_per_z, frfs.accel_per_z)
    if any(p.freq_hz.shape != parts[0].freq_hz.shape or np.any(p.freq_hz != parts[0].freq_hz) for p in parts):
        raise AnalysisInputError("the four-post FRFs must share their frequencies")
    use = parts[0].reliable & parts[1].reliable & parts[2].reliable
    if use.sum() < 8:
        raise AnalysisInputError(f"only {int(use.sum())} bins reliable in all three FRFs; at least 8 needed")
    h = np.concatenate([p.value[use] for p in parts])
    s = np.concatenate([p.sigma[use] for p in parts])
    return _PostData(parts[0].freq_hz[use], h, np.sqrt(s**2 + (RELATIVE_SIGMA_FLOOR * np.abs(h)) ** 2))


def _suspension_start(frfs: FourPostFrfs) -> dict[str, float]:
    """Start values from the apparent mass ``M = F_wfs / a_hub`` alone, never from presets.

    Well above the body mode ``M ~ m_h - (k_s + j w d_s) / w^2`` (linear least squares over the
    upper half of the band); well below it ``M ~ m_h + m_B`` (the lowest reliable bins).
    """
    m = frfs.apparent_mass_above()
    f, h = m.freq_hz[m.reliable], m.value[m.reliable]
    if f.size < 8:
        raise AnalysisInputError("too few bins where both F_wfs/Z and a_hub/Z are reliable")
    w = 2 * np.pi * f
    high = f >= 0.5 * f[-1]
    re = np.linalg.lstsq(np.stack([np.ones(high.sum()), -1 / w[high] ** 2], 1), h.real[high], rcond=None)[0]
    m_h = max(float(re[0]), 0.5)
    d_s = max(float(np.median(-h.imag[high] * w[high])), 1.0)
    m_b = max(float(np.median(h.real[:5])) - m_h, m_h)
    k_s = float(re[1]) if re[1] > 0 else m_b * (2 * np.pi * 2 * f[0]) ** 2
    return {
        "unsprung_mass_above_kg": m_h,
        "suspension_stiffness_n_per_m": k_s,
        "suspension_damping_ns_per_m": d_s,
        "body_mass_kg": m_b,
    }


def _bounds(name: str) -> tuple[float, float]:
    return {
        "unsprung_mass_above_kg": (0.1, 1e3),
        "suspension_stiffness_n_per_m": (1e2, 1e7),
        "suspension_damping_ns_per_m": (0.0, 1e5),
        "body_mass_kg": (1.0, 1e4),
        DELAY: (-5e-3, 5e-3),
        FRICTION: (0.0, 1e5),
    }[name]


def _resolution(name: str, values: Mapping[str, float]) -> float:
    if name == DELAY:
        return max(relative_resolution(name, values), DELAY_RESOLUTION_S)
    return relative_resolution(name, values)


def _objects(values: Mapping[str, float], friction: PostFriction) -> tuple[Suspension, PostFriction]:
    suspension = Suspension(
        unsprung_mass_above_kg=values["unsprung_mass_above_kg"],
        stiffness_n_per_m=values["suspension_stiffness_n_per_m"],
        damping_ns_per_m=values["suspension_damping_ns_per_m"],
        body_mass_kg=values["body_mass_kg"],
    )
    return suspension, replace(friction, friction_force_n=values[FRICTION])


def fit_quarter_car(
    frfs: FourPostFrfs,
    *,
    model: TyreModel,
    tyre: Tyre,
    sensor: WfsSensor,
    amplitude_m: float,
    rubber: RubberTerms = LINEAR,
    sensor_source: str = "given",
) -> QuarterCarFit:
    """Identify the quarter car from four-post FRFs (see the module docstring).

    ``tyre``/``rubber``/``model``: the tyre below the sensor as identified on the shaker at the
    same pressure (its ``wheel_mass_kg`` is the weighed mass below the sensor); the tyre's loss on
    the post is a friction force fitted there (:class:`PostFriction`), over the deflection the
    sweep's displacement amplitude ``amplitude_m`` (measured) gives it. ``sensor_source``: where
    the sensor comes from, as ``taken_as_given`` names it (``from the hammer test``).
    """
    model = TyreModel(model)
    data = _post_data(frfs)
    n = data.freq_hz.size
    w = 2 * np.pi * data.freq_hz
    # the loss element's deflection from the measured contact force, with the shaker's loss in the
    # tyre element (the post's changes it by well under 1 %: the loss is a few per cent of k)
    deflection = loss_element_deflection(model, tyre, data.freq_hz, data.h[n : 2 * n], rubber)
    friction = PostFriction(float("nan"), float(amplitude_m), data.freq_hz, np.abs(deflection))
    start = {
        **_suspension_start(frfs),
        DELAY: 0.0,
        # the shaker's loss (at least 1 % of k) at the plate's amplitude: F = pi A h / 4
        FRICTION: np.pi
        * amplitude_m
        * max(rubber.hysteretic_damping_n_per_m, 0.01 * tyre.stiffness_n_per_m)
        / 4,
    }
    scale = {**{name: abs(v) for name, v in start.items()}, DELAY: 1e-3}

    def residuals(values: Mapping[str, float]) -> np.ndarray:
        suspension, friction_now = _objects(values, friction)
        rubber_now = replace(rubber, hysteretic_damping_n_per_m=friction_now.loss_n_per_m(data.freq_hz))
        wfs, contact, accel = quarter_car_response(
            model, tyre, suspension, sensor, data.freq_hz, rubber=rubber_now
        )
        accel = accel * np.exp(-1j * w * values[DELAY])
        r = (np.concatenate([wfs, contact, accel]) - data.h) / data.sigma * np.sqrt(2.0)
        return np.concatenate([r.real, r.imag])

    bounds = {name: _bounds(name) for name in start}
    fit = weighted_fit(
        residuals,
        start,
        bounds,
        scale=scale,
        resolution=_resolution,
        covariance_factor=correlated_residual_factor(6, floor=HANN_ENBW_BINS),
    )
    suspension, friction = _objects(fit.values, friction)
    (f_b, z_b), (f_w, z_w) = quarter_car_modes(
        model, tyre, suspension, sensor, rubber, loss_n_per_m=friction.loss_n_per_m
    )
    ci_b, ci_w = _mode_intervals(fit, tyre, model, sensor, rubber=rubber, friction=friction)
    given = [
        "tyre stiffness, viscous damping, tread mass and stiffness rise (shaker identification)",
        "wheel_mass_kg below the sensor (weighed)",
        f"sensor stiffness and damping ({sensor_source})",
    ]
    if model is TyreModel.WHEEL_TREAD_SIDEWALL:
        given.append("sidewall mass and stiffnesses (shaker identification)")
    return QuarterCarFit(
        model=model,
        tyre=tyre,
        rubber=rubber,
        friction=friction,
        suspension=suspension,
        accelerometer_delay_s=fit.values[DELAY],
        lsq=fit,
        taken_as_given=tuple(given),
        body_frequency_hz=f_b,
        body_frequency_ci95_hz=ci_b,
        body_damping_ratio=z_b,
        wheel_frequency_hz=f_w,
        wheel_frequency_ci95_hz=ci_w,
        wheel_damping_ratio=z_w,
        band_hz=(float(data.freq_hz[0]), float(data.freq_hz[n - 1])),
    )


def _mode_intervals(
    fit: LsqResult,
    tyre: Tyre,
    model: TyreModel,
    sensor: WfsSensor,
    *,
    rubber: RubberTerms,
    friction: PostFriction,
) -> tuple[float, float]:
    """95 % half-widths of the body and wheel frequencies: ``1.96 sqrt(g^T C g)`` with ``g`` the
    central-difference gradient over the fitted parameters."""
    names = [n for n in fit.values if n != DELAY]  # the accelerometer's delay moves no mode
    idx = [list(fit.values).index(n) for n in names]
    cov = fit.covariance[np.ix_(idx, idx)]
    grad = np.zeros((2, len(names)))
    for j, name in enumerate(names):
        step = 1e-4 * abs(fit.values[name]) or 1e-6
        freqs = []
        for sign in (1, -1):
            values = {**fit.values, name: fit.values[name] + sign * step}
            suspension, friction_now = _objects(values, friction)
            (f_b, _), (f_w, _) = quarter_car_modes(
                model, tyre, suspension, sensor, rubber, loss_n_per_m=friction_now.loss_n_per_m
            )
            freqs.append((f_b, f_w))
        grad[:, j] = (np.array(freqs[0]) - np.array(freqs[1])) / (2 * step)
    half = Z95 * np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", grad, cov, grad), 0.0))
    return float(half[0]), float(half[1])
