"""The closed-form shaker responses equal the mechanical network's, for every model."""

from dataclasses import replace

import numpy as np
import pytest

from bench.analysis.shaker_models import RubberTerms, hub_driven_response, shaker_response
from bench.models.benches import TyreModel, shaker_bench
from bench.models.network import Base, MechanicalNetwork
from bench.models.parameters import Tyre, WfsSensor

FREQ = np.array([0.3, 1.0, 7.0, 25.0, 38.0, 55.0, 100.0, 400.0])
TYRE = Tyre(stiffness_n_per_m=310e3, damping_ns_per_m=140.0, tread_mass_kg=4.5, sidewall_mass_kg=1.7)
SENSOR = WfsSensor(mass_kg=4.1, eigenfrequency_hz=1800.0, damping_ratio=0.03)


@pytest.mark.parametrize("model", list(TyreModel))
def test_linear_closed_form_equals_network(model):
    net = shaker_bench(model, TYRE, SENSOR).frequency_response(FREQ)
    wfs, contact = shaker_response(model, TYRE, SENSOR, FREQ)
    np.testing.assert_allclose(wfs, net["f_wfs"], rtol=1e-9)
    np.testing.assert_allclose(contact, net["f_contact"], rtol=1e-9)


@pytest.mark.parametrize("model", list(TyreModel))
def test_rubber_terms_equal_a_network_linearised_per_frequency(model):
    """k(f) and d + h/w at each frequency: the network rebuilt with those values gives the same."""
    rubber = RubberTerms(stiffness_rise_per_decade=0.05, hysteretic_damping_n_per_m=9e3)
    wfs, contact = shaker_response(model, TYRE, SENSOR, FREQ, rubber)
    for i, f in enumerate(FREQ):
        tyre = replace(
            TYRE,
            stiffness_n_per_m=TYRE.stiffness_n_per_m * float(rubber.stiffness_factor(f)),
            damping_ns_per_m=float(rubber.equivalent_damping_ns_per_m(TYRE, f)),
        )
        net = shaker_bench(model, tyre, SENSOR).frequency_response(f)
        assert wfs[i] == pytest.approx(net["f_wfs"][0], rel=1e-9)
        assert contact[i] == pytest.approx(net["f_contact"][0], rel=1e-9)


@pytest.mark.parametrize("model", list(TyreModel))
def test_hub_driven_closed_form_equals_network(model):
    """The shaker network with the roles swapped: the hub is the driven base, the contact is fixed;
    the contact force is then the sum of the forces of the links attached to the contact node."""
    bench = shaker_bench(model, TYRE, SENSOR)
    swapped = MechanicalNetwork(bench.masses, bench.links, base=Base("hub"), fixed=("base",))
    net = swapped.frequency_response(FREQ)
    contact = sum(net[f"f_{link.name}"] for link in bench.links if link.lower == "base")
    wfs, contact_cf = hub_driven_response(model, TYRE, SENSOR, FREQ)
    np.testing.assert_allclose(wfs, net["f_wfs"], rtol=1e-9)
    np.testing.assert_allclose(contact_cf, contact, rtol=1e-9)
