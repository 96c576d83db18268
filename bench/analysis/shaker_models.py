"""Closed-form shaker-bench responses of the paper's Models 1-3, for fast identification.

The shaker bench clamps the hub; the plate displacement ``Z`` drives the contact. With the sensor
as a spring/damper ``K_s = k_s + j w d_s`` between the rim and the clamped hub, and the tyre
element ``T = k(f) + j (w d + h)``:

- Models 1 and 2 (rim mass ``m_r``; tread ``m_T`` moving with the plate, zero in Model 1)::

      (-m_r w^2 + T + K_s) z_r = T Z,   F_wfs = K_s z_r,   F_contact = -m_T w^2 Z + T (Z - z_r)

- Model 3 (air spring ``A = k(f)`` base-rim; sidewall mass ``m_sw`` on ``L = k_lower`` from the
  base and ``U = k_upper + j (w d + h)`` to the rim)::

      (-m_sw w^2 + L + U) z_sw - U z_r = L Z
      -U z_sw + (-m_r w^2 + A + U + K_s) z_r = A Z
      F_wfs = K_s z_r,   F_contact = -m_T w^2 Z + A (Z - z_r) + L (Z - z_sw)

The rubber terms beyond the paper's linear elements are optional: a stiffness rising with the
logarithm of frequency, ``k(f) = k (1 + rate log10(max(f, f_min) / f_ref))``, and a hysteretic
(rate-independent) damping ``h`` in N/m next to the viscous ``d``. With both zero this is exactly
the linear network of :func:`bench.models.benches.shaker_bench` (tested equal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor

#: Reference and lowest frequency of the logarithmic stiffness law.
STIFFNESS_REFERENCE_HZ = 10.0
STIFFNESS_MIN_HZ = 0.5


@dataclass(frozen=True)
class RubberTerms:
    """Departures from the linear spring/damper: ``k(f)`` rise per decade and hysteretic damping
    (N/m; an array over the frequencies a response is evaluated at for a loss that changes with
    them, as the tyre's friction on the four-post bench)."""

    stiffness_rise_per_decade: float = 0.0
    hysteretic_damping_n_per_m: float | np.ndarray = 0.0

    def stiffness_factor(self, freq_hz: np.ndarray) -> np.ndarray:
        f = np.maximum(np.asarray(freq_hz, dtype=float), STIFFNESS_MIN_HZ)
        return 1.0 + self.stiffness_rise_per_decade * np.log10(f / STIFFNESS_REFERENCE_HZ)

    def equivalent_damping_ns_per_m(self, tyre: Tyre, freq_hz: np.ndarray) -> np.ndarray:
        """Viscous damping equivalent to ``d`` plus the hysteretic term at each frequency."""
        w = 2 * np.pi * np.asarray(freq_hz, dtype=float)
        return tyre.damping_ns_per_m + self.hysteretic_damping_n_per_m / w


#: No rubber terms: the paper's linear spring and damper.
LINEAR = RubberTerms()


def _dynamic_terms(
    tyre: Tyre, sensor: WfsSensor, freq_hz: np.ndarray, rubber: RubberTerms
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Circular frequency, sensor dynamic stiffness, tyre (air) stiffness and tyre loss term."""
    f = np.asarray(freq_hz, dtype=float)
    w = 2 * np.pi * f
    ks = sensor.stiffness_n_per_m + 1j * w * sensor.damping_ns_per_m
    k = tyre.stiffness_n_per_m * rubber.stiffness_factor(f)
    loss = 1j * (w * tyre.damping_ns_per_m + rubber.hysteretic_damping_n_per_m)
    return w, ks, k, loss


def _sidewall_system(tyre: Tyre, w: np.ndarray, ks: np.ndarray, k: np.ndarray, loss: np.ndarray):
    """Model 3's sidewall/rim equations: lower and upper sidewall stiffness, the 2x2 dynamic
    stiffness ``[[a11, -upper], [-upper, a22]]`` of (sidewall, rim) and its determinant."""
    m_r = tyre.wheel_mass_kg - tyre.tread_mass_kg - tyre.sidewall_mass_kg
    lower = tyre.sidewall_lower_stiffness_n_per_m
    upper = tyre.sidewall_upper_stiffness_n_per_m + loss
    a11 = -tyre.sidewall_mass_kg * w**2 + lower + upper
    a22 = -m_r * w**2 + k + upper + ks
    return lower, upper, a11, a22, a11 * a22 - upper**2


def shaker_response(
    model: TyreModel,
    tyre: Tyre,
    sensor: WfsSensor,
    freq_hz: np.ndarray,
    rubber: RubberTerms = LINEAR,
) -> tuple[np.ndarray, np.ndarray]:
    """``(F_wfs / Z, F_contact / Z)`` of the shaker bench, complex, N/m (see the module docstring)."""
    w, ks, k, loss = _dynamic_terms(tyre, sensor, freq_hz, rubber)
    model = TyreModel(model)
    if model is TyreModel.WHEEL_TREAD_SIDEWALL:
        lower, upper, a11, a22, det = _sidewall_system(tyre, w, ks, k, loss)
        z_sw = (lower * a22 + upper * k) / det
        z_r = (a11 * k + upper * lower) / det
        contact = -tyre.tread_mass_kg * w**2 + k * (1 - z_r) + lower * (1 - z_sw)
        return ks * z_r, contact
    m_t = tyre.tread_mass_kg if model is TyreModel.WHEEL_TREAD else 0.0
    tyre_el = k + loss
    z_r = tyre_el / (-(tyre.wheel_mass_kg - m_t) * w**2 + tyre_el + ks)
    return ks * z_r, -m_t * w**2 + tyre_el * (1 - z_r)


def _element_partials(
    names: tuple[str, ...], tyre: Tyre, rubber: RubberTerms, f: np.ndarray, w: np.ndarray
) -> dict[str, np.ndarray]:
    """How each parameter of ``names`` moves the elements of the network, one row per name and
    one column per frequency: ``k`` the (air) stiffness ``k(f)``, ``loss`` the tyre's loss term,
    ``upper``/``lower`` the sidewall springs, ``tread``/``sidewall`` the masses."""
    elements = ("k", "loss", "upper", "lower", "tread", "sidewall")
    rows = {e: np.zeros((len(names), f.size), complex) for e in elements}
    for i, name in enumerate(names):
        if name == "stiffness_n_per_m":
            rows["k"][i] = rubber.stiffness_factor(f)
        elif name == "stiffness_rise_per_decade":
            decades = np.log10(np.maximum(f, STIFFNESS_MIN_HZ) / STIFFNESS_REFERENCE_HZ)
            rows["k"][i] = tyre.stiffness_n_per_m * decades
        elif name == "damping_ns_per_m":
            rows["loss"][i] = 1j * w
        elif name == "hysteretic_damping_n_per_m":
            rows["loss"][i] = 1j
        else:
            element = {
                "sidewall_upper_stiffness_n_per_m": "upper",
                "sidewall_lower_stiffness_n_per_m": "lower",
                "tread_mass_kg": "tread",
                "sidewall_mass_kg": "sidewall",
            }[name]
            rows[element][i] = 1.0
    return rows


#: The parameters each model's shaker response depends on (besides the rubber terms).
MODEL_PARAMETERS: dict[TyreModel, tuple[str, ...]] = {
    TyreModel.WHEEL: ("stiffness_n_per_m", "damping_ns_per_m"),
    TyreModel.WHEEL_TREAD: ("stiffness_n_per_m", "damping_ns_per_m", "tread_mass_kg"),
    TyreModel.WHEEL_TREAD_SIDEWALL: (
        "stiffness_n_per_m",
        "damping_ns_per_m",
        "tread_mass_kg",
        "sidewall_mass_kg",
        "sidewall_lower_stiffness_n_per_m",
        "sidewall_upper_stiffness_n_per_m",
    ),
}
#: The rubber terms' parameters (:class:`RubberTerms`), which any model may take.
RUBBER_PARAMETERS = ("stiffness_rise_per_decade", "hysteretic_damping_n_per_m")


def shaker_response_derivatives(
    model: TyreModel,
    tyre: Tyre,
    sensor: WfsSensor,
    freq_hz: np.ndarray,
    rubber: RubberTerms,
    *,
    names: tuple[str, ...],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`shaker_response` and its exact partial derivatives with respect to the parameters
    ``names`` (fields of :class:`Tyre` and :class:`RubberTerms`; the wheel mass and sensor held):
    ``(wfs, contact, d_wfs, d_contact)``, the derivatives with one row per name (units of the
    response per unit of the parameter).

    Implicit differentiation of the network's equations ``K z = b`` (``z``: rim, and sidewall in
    Model 3; ``b``: what the unit plate displacement drives): ``dz = K^-1 (db - dK z)``, then the
    forces' own dependence on the elements (see the module docstring for ``K``, ``b`` and the
    forces). A parameter the model does not have raises ``ValueError``.
    """
    model = TyreModel(model)
    allowed = MODEL_PARAMETERS[model] + RUBBER_PARAMETERS
    unknown = [n for n in names if n not in allowed]
    if unknown:
        raise ValueError(f"Model {int(model)}'s shaker response has no parameter {unknown}")
    f = np.asarray(freq_hz, dtype=float)
    w, ks, k, loss = _dynamic_terms(tyre, sensor, f, rubber)
    w2 = w**2
    p = _element_partials(names, tyre, rubber, f, w)
    dk, dm_t = p["k"], p["tread"]
    if model is TyreModel.WHEEL_TREAD_SIDEWALL:
        lower, upper, a11, a22, det = _sidewall_system(tyre, w, ks, k, loss)
        z_sw = (lower * a22 + upper * k) / det
        z_r = (a11 * k + upper * lower) / det
        dl, du, dm_sw = p["lower"], p["upper"] + p["loss"], p["sidewall"]
        da11 = -dm_sw * w2 + dl + du
        da22 = (dm_t + dm_sw) * w2 + dk + du
        r_sw = dl - (da11 * z_sw - du * z_r)  # db - dK z, sidewall row
        r_r = dk - (da22 * z_r - du * z_sw)  # rim row
        dz_sw = (a22 * r_sw + upper * r_r) / det
        dz_r = (upper * r_sw + a11 * r_r) / det
        d_contact = -dm_t * w2 + dk * (1 - z_r) - k * dz_r + dl * (1 - z_sw) - lower * dz_sw
        contact = -tyre.tread_mass_kg * w2 + k * (1 - z_r) + lower * (1 - z_sw)
        return ks * z_r, contact, ks * dz_r, d_contact
    m_t = tyre.tread_mass_kg if model is TyreModel.WHEEL_TREAD else 0.0
    tyre_el = k + loss
    dyn = -(tyre.wheel_mass_kg - m_t) * w2 + tyre_el + ks
    z_r = tyre_el / dyn
    d_el = dk + p["loss"]
    dz_r = (d_el - (dm_t * w2 + d_el) * z_r) / dyn
    d_contact = -dm_t * w2 + d_el * (1 - z_r) - tyre_el * dz_r
    return ks * z_r, -m_t * w2 + tyre_el * (1 - z_r), ks * dz_r, d_contact


def hub_driven_response(
    model: TyreModel,
    tyre: Tyre,
    sensor: WfsSensor,
    freq_hz: np.ndarray,
    rubber: RubberTerms = LINEAR,
) -> tuple[np.ndarray, np.ndarray]:
    """``(F_wfs / z_hub, F_contact / z_hub)`` with the contact held still and the hub moved, N/m.

    Together with :func:`shaker_response` (hub held, contact moved) this is the whole linear
    behaviour of what lies below the sensor, whatever stands above it (suspension, body). Models 1/2::

        (-m_r w^2 + T + K_s) z_r = K_s z_hub,  F_wfs = K_s (z_r - z_hub),  F_contact = -T z_r

    Model 3: the sidewall equations with ``Z = 0`` and ``K_s z_hub`` driving the rim;
    ``F_contact = -A z_r - L z_sw``.
    """
    w, ks, k, loss = _dynamic_terms(tyre, sensor, freq_hz, rubber)
    model = TyreModel(model)
    if model is TyreModel.WHEEL_TREAD_SIDEWALL:
        lower, upper, a11, _, det = _sidewall_system(tyre, w, ks, k, loss)
        z_r, z_sw = a11 * ks / det, upper * ks / det
        return ks * (z_r - 1), -k * z_r - lower * z_sw
    m_t = tyre.tread_mass_kg if model is TyreModel.WHEEL_TREAD else 0.0
    tyre_el = k + loss
    z_r = ks / (-(tyre.wheel_mass_kg - m_t) * w**2 + tyre_el + ks)
    return ks * (z_r - 1), -tyre_el * z_r


def loss_element_deflection(
    model: TyreModel,
    tyre: Tyre,
    freq_hz: np.ndarray,
    contact_per_z: np.ndarray,
    rubber: RubberTerms = LINEAR,
) -> np.ndarray:
    """The deflection of the element that carries the tyre's loss per unit contact displacement,
    complex, from the contact force the tyre passes, ``contact_per_z = F_contact / Z`` (measured:
    whatever moves the rim, a clamped hub or a car on a post). Models 1/2: the tyre element,
    ``(Z - z_r) / Z = (F_contact / Z + m_T w^2) / T``. Model 3: the upper sidewall, ``(z_sw - z_r) / Z``,
    with ``z_sw`` from the sidewall's equation and ``z_r`` from the contact force
    ``F_contact / Z = -m_T w^2 + A (1 - z_r/Z) + L (1 - z_sw/Z)``."""
    f = np.asarray(freq_hz, dtype=float)
    w = 2 * np.pi * f
    k = tyre.stiffness_n_per_m * rubber.stiffness_factor(f)
    loss = 1j * (w * tyre.damping_ns_per_m + rubber.hysteretic_damping_n_per_m)
    model = TyreModel(model)
    m_t = 0.0 if model is TyreModel.WHEEL else tyre.tread_mass_kg
    tyre_force = np.asarray(contact_per_z) + m_t * w**2  # the springs' force per unit Z
    if model is not TyreModel.WHEEL_TREAD_SIDEWALL:
        return tyre_force / (k + loss)
    lower = tyre.sidewall_lower_stiffness_n_per_m
    upper = tyre.sidewall_upper_stiffness_n_per_m + loss
    d = lower + upper - tyre.sidewall_mass_kg * w**2  # z_sw = (L Z + U z_r) / d
    rim = (k + lower - lower**2 / d - tyre_force) / (k + lower * upper / d)
    return (lower + upper * rim) / d - rim
