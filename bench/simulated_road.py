"""A road drive on the simulated quarter car: what the WFS, the hub accelerometer and the post read
while the car's corner drives an ISO 8608 road, with the true contact force beside them.

A composition root like :mod:`bench.simulated_campaign`: it joins the road model
(:mod:`bench.models.road`) to the plant (:mod:`simulators.plant`). The road is the contact's
displacement, played through the stiff ideal servo of the simulated post
(:class:`simulators.plant.IdealServo`, 200 Hz: a road's band ends far below it), so the same drive
also stands for a four-post bench replaying the road; the true contact force is the plant's, from
the motion the contact really made.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bench.analysis.records import DISPLACEMENT, HUB_ACCELERATION, PLATE_FORCE, WFS_FORCE
from bench.models.road import RoadDrive
from bench.models.setup import BenchSetup
from bench.simulated_campaign import TRUTH_CHANNEL
from simulators.plant import IdealServo, PlantSimulator, SampledDrive, SensorRealism

#: Frequencies over the road's band on which its tyre is linearised (a smooth density: a fine grid
#: changes the linear tyre by far less than 1e-4).
TYRE_GRID_POINTS = 4000
#: Raised-cosine tapers at the drive's ends (s): the car starts and stops at rest on its post.
ROAD_TAPER_S = 0.5


@dataclass(frozen=True)
class RoadRecord:
    """A road drive recorded: ``channels`` at ``sample_rate_hz`` (``fz_wfs_n``, ``a_hub_m_s2``,
    ``z_base_m``, ``f_plate_n`` as the bench's sensors read them, and the true contact force
    ``f_contact_n``), all of the drive's length, sample ``i`` at ``i / sample_rate_hz``."""

    drive: RoadDrive
    sample_rate_hz: float
    channels: dict[str, np.ndarray]


def simulate_road(setup: BenchSetup, drive: RoadDrive, *, seed: int) -> RoadRecord:
    """The quarter car ``setup`` driving ``drive`` (tapered in and out by :data:`ROAD_TAPER_S`),
    sensor noise seeded by ``seed``, recorded at the drive's sample rate. A non-linear tyre is
    linearised for the road's spectrum (:meth:`BenchSetup.broadband_tyre`: statistical
    linearisation of its friction, its stiffness at the deflection's equivalent frequency)."""
    freq_hz = np.linspace(drive.band_hz[0], drive.band_hz[1], TYRE_GRID_POINTS)
    tyre = setup.broadband_tyre(freq_hz, drive.temporal_psd_m2_per_hz(freq_hz))
    linear = replace(setup, tyre=tyre, nonlinearity=None)
    plant = PlantSimulator(
        linear, realism=SensorRealism(seed=seed), actuator=IdealServo(), output_rate_hz=drive.sample_rate_hz
    )
    waveform = SampledDrive(drive.displacement_m, drive.sample_rate_hz, ROAD_TAPER_S, ROAD_TAPER_S)
    record = plant.simulate(waveform, extra_s=1 / drive.sample_rate_hz)
    names = (WFS_FORCE, HUB_ACCELERATION, DISPLACEMENT, PLATE_FORCE, TRUTH_CHANNEL)
    return RoadRecord(drive, plant.output_rate_hz, {name: record[name] for name in names})
