"""The paper's models (section 3) as mechanical networks on the shaker bench and the four-post bench.

Node and output names are the same in every model so that the simulator and the analysis need not
know which model they face:

- ``base``: shaker plate / post (prescribed motion); in Models 2 and 3 the tread moves with it.
- ``rim``: the mass directly below the sensor (the whole 29 kg wheel in Model 1).
- ``sidewall``: Model 3 only.
- ``hub``: above the sensor; fixed on the shaker bench, the remaining unsprung mass on a quarter car.
- ``body``: quarter-car body.

Outputs (per :class:`~bench.models.network.MechanicalNetwork`): ``f_wfs`` (sensor force),
``f_contact`` (true tyre contact force), ``f_plate`` (plate load-cell force before plate-mass
correction), ``a_hub`` (hub acceleration), ``z_rim``, ``z_base``, ... .
"""

from __future__ import annotations

from enum import IntEnum

from bench.models.network import Base, Link, Mass, MechanicalNetwork
from bench.models.parameters import Rig, Suspension, Tyre, WfsSensor


class TyreModel(IntEnum):
    """The paper's three levels of detail."""

    WHEEL = 1  # Model 1: one wheel mass on the tyre spring/damper
    WHEEL_TREAD = 2  # Model 2: tread mass separated from the rim by the tyre spring/damper
    WHEEL_TREAD_SIDEWALL = 3  # Model 3: sidewall mass between two springs, parallel air spring


def _tyre_parts(model: TyreModel, tyre: Tyre) -> tuple[list[Mass], list[Link], float]:
    """Masses and links from the contact (``base``) to the ``rim``, and the mass moving with the base."""
    model = TyreModel(model)
    if model is TyreModel.WHEEL:
        masses = [Mass("rim", tyre.wheel_mass_kg)]
        links = [Link("tyre", "base", "rim", tyre.stiffness_n_per_m, tyre.damping_ns_per_m)]
        return masses, links, 0.0
    if model is TyreModel.WHEEL_TREAD:
        masses = [Mass("rim", tyre.wheel_mass_kg - tyre.tread_mass_kg)]
        links = [Link("tyre", "base", "rim", tyre.stiffness_n_per_m, tyre.damping_ns_per_m)]
        return masses, links, tyre.tread_mass_kg
    rim_kg = tyre.wheel_mass_kg - tyre.tread_mass_kg - tyre.sidewall_mass_kg
    masses = [Mass("sidewall", tyre.sidewall_mass_kg), Mass("rim", rim_kg)]
    links = [
        Link("air", "base", "rim", tyre.stiffness_n_per_m),
        Link("sidewall_lower", "base", "sidewall", tyre.sidewall_lower_stiffness_n_per_m),
        Link(
            "sidewall_upper", "sidewall", "rim", tyre.sidewall_upper_stiffness_n_per_m, tyre.damping_ns_per_m
        ),
    ]
    return masses, links, tyre.tread_mass_kg


def _sensor_link(sensor: WfsSensor) -> Link:
    return Link("wfs", "rim", "hub", sensor.stiffness_n_per_m, sensor.damping_ns_per_m)


def shaker_bench(
    model: TyreModel, tyre: Tyre, sensor: WfsSensor | None = None, rig: Rig | None = None
) -> MechanicalNetwork:
    """Wheel centre clamped to the frame, tyre excited at the contact patch (paper, 2.3)."""
    sensor, rig = sensor or WfsSensor(), rig or Rig()
    masses, links, contact_kg = _tyre_parts(model, tyre)
    return MechanicalNetwork(
        masses=masses,
        links=[*links, _sensor_link(sensor)],
        base=Base("base", contact_mass_kg=contact_kg, plate_mass_kg=rig.plate_mass_kg),
        fixed=("hub",),
    )


def quarter_car(
    model: TyreModel,
    tyre: Tyre,
    suspension: Suspension | None = None,
    sensor: WfsSensor | None = None,
    rig: Rig | None = None,
) -> MechanicalNetwork:
    """A quarter vehicle standing on a post of the four-post bench (paper, 2.4 and 3.2)."""
    suspension, sensor = suspension or Suspension(), sensor or WfsSensor()
    rig = rig or Rig(plate_mass_kg=15.0)
    masses, links, contact_kg = _tyre_parts(model, tyre)
    masses += [Mass("hub", suspension.unsprung_mass_above_kg), Mass("body", suspension.body_mass_kg)]
    links += [
        _sensor_link(sensor),
        Link("suspension", "hub", "body", suspension.stiffness_n_per_m, suspension.damping_ns_per_m),
    ]
    return MechanicalNetwork(
        masses=masses,
        links=links,
        base=Base("base", contact_mass_kg=contact_kg, plate_mass_kg=rig.plate_mass_kg),
        fixed=(),
    )


def free_run(rig: Rig | None = None) -> MechanicalNetwork:
    """The shaker without a wheel: the load cell sees only the plate (identifies m_comp)."""
    rig = rig or Rig()
    return MechanicalNetwork(
        masses=[], links=[], base=Base("base", plate_mass_kg=rig.plate_mass_kg), fixed=("hub",)
    )


def hammer_test(sensor: WfsSensor | None = None) -> MechanicalNetwork:
    """The bare sensor on a rigid foundation, struck by a hammer (paper, 2.2 and Figure 3).

    The struck node is the sensor's mass (``rim`` side of the sensing element); the hammer force
    is the input ``f_rim``.
    """
    sensor = sensor or WfsSensor()
    return MechanicalNetwork(
        masses=[Mass("rim", sensor.mass_kg)],
        links=[_sensor_link(sensor)],
        fixed=("hub",),
        force_inputs=("rim",),
    )
