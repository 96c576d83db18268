"""A road drive on the simulated quarter car: what the WFS, the hub accelerometer and the post read
while the car's corner drives an ISO 8608 road, with the true contact force beside them.

A composition root like :mod:`bench.simulated_campaign`: it joins the road model
(:mod:`bench.models.road`) to the plant (:mod:`simulators.plant`). The road is the contact's
displacement, played through the stiff ideal servo of the simulated post
(:class:`simulators.plant.IdealServo`, 200 Hz: a road's band ends far below it), so the same drive
also stands for a four-post bench replaying the road; the true contact force is the plant's, from
the motion the contact really made.

:func:`validate_on_road` compensates such a drive with a campaign's identification, as
``wfsbench compensate`` does, and compares the raw, hub-acceleration-compensated and
model-compensated forces with the truth (docs/compensate.md, *Validation on a simulated road*). A
road is read by the bench's own sensors (those of the simulated campaign: its accelerometer is the
one the campaign's four-post run measured), or by others (:func:`other_sensors`: a road measured
with another car's accelerometer and another logger).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bench.analysis.campaign import CampaignAnalysis
from bench.analysis.compensation import advance_acceleration, hub_acceleration_compensation
from bench.analysis.records import DISPLACEMENT, HUB_ACCELERATION, PLATE_FORCE, WFS_FORCE
from bench.analysis.road_validation import (
    ERROR_BAND_HZ,
    RoadValidation,
    band_limited,
    band_rms,
    coverage,
    force_errors,
)
from bench.app.compensate import prepare_compensation
from bench.models.road import RoadDrive
from bench.models.setup import BenchSetup
from bench.simulated_campaign import TRUTH_CHANNEL
from bench.store.measurement import MEASUREMENT_CHANNELS, Measurement
from bench.store.measurement_chain import CAMPAIGN_LAG, MeasurementChain, Stated
from simulators.plant import IdealServo, PlantSimulator, SampledDrive, SensorRealism

#: Frequencies over the road's band on which its tyre is linearised (a smooth density: a fine grid
#: changes the linear tyre by far less than 1e-4).
TYRE_GRID_POINTS = 4000
#: Raised-cosine tapers at the drive's ends (s): the car starts and stops at rest on its post.
ROAD_TAPER_S = 0.5
#: What a road read by the bench's own sensors states of its chain: the campaign's accelerometer.
BENCH_CHAIN = MeasurementChain(
    hub_lag_ms=Stated(CAMPAIGN_LAG, "the simulated road, read by the bench's sensors,")
)


def other_sensors(seed: int) -> SensorRealism:
    """Sensors other than the bench's, as a road measured with another car and logger has them: a
    hub accelerometer of half the bandwidth (300 Hz: twice the lag, 0.75 ms) and a WFS converter
    three times as noisy (about 3 N rms per sample at 1 kHz, where the bench's has about 1 N)."""
    bench = SensorRealism(seed=seed)
    return replace(
        bench,
        accelerometer_bandwidth_hz=bench.accelerometer_bandwidth_hz / 2,
        wfs_noise_n=3 * bench.wfs_noise_n,
    )


@dataclass(frozen=True)
class RoadRecord:
    """A road drive recorded: ``channels`` at ``sample_rate_hz`` (``fz_wfs_n``, ``a_hub_m_s2``,
    ``z_base_m``, ``f_plate_n`` as the bench's sensors read them, and the true contact force
    ``f_contact_n``), all of the drive's length, sample ``i`` at ``i / sample_rate_hz``."""

    drive: RoadDrive
    sample_rate_hz: float
    channels: dict[str, np.ndarray]


def simulate_road(
    setup: BenchSetup, drive: RoadDrive, *, seed: int, sensors: SensorRealism | None = None
) -> RoadRecord:
    """The quarter car ``setup`` driving ``drive`` (tapered in and out by :data:`ROAD_TAPER_S`),
    read by ``sensors`` (default: the bench's, noise seeded by ``seed``), recorded at the drive's
    sample rate. A non-linear tyre is
    linearised for the road's spectrum (:meth:`BenchSetup.broadband_tyre`: statistical
    linearisation of its friction, its stiffness at the deflection's equivalent frequency)."""
    freq_hz = np.linspace(drive.band_hz[0], drive.band_hz[1], TYRE_GRID_POINTS)
    tyre = setup.broadband_tyre(freq_hz, drive.temporal_psd_m2_per_hz(freq_hz))
    linear = replace(setup, tyre=tyre, nonlinearity=None)
    plant = PlantSimulator(
        linear,
        realism=sensors or SensorRealism(seed=seed),
        actuator=IdealServo(),
        output_rate_hz=drive.sample_rate_hz,
    )
    waveform = SampledDrive(drive.displacement_m, drive.sample_rate_hz, ROAD_TAPER_S, ROAD_TAPER_S)
    record = plant.simulate(waveform, extra_s=1 / drive.sample_rate_hz)
    names = (WFS_FORCE, HUB_ACCELERATION, DISPLACEMENT, PLATE_FORCE, TRUTH_CHANNEL)
    return RoadRecord(drive, plant.output_rate_hz, {name: record[name] for name in names})


def validate_on_road(
    analysis: CampaignAnalysis,
    setup: BenchSetup,
    drive: RoadDrive,
    *,
    pressure_bar: float,
    seed: int,
    sensors: SensorRealism | None = None,
    chain: MeasurementChain | None = None,
) -> RoadValidation:
    """Drive ``setup`` over ``drive`` (:func:`simulate_road`, read by ``sensors``: the bench's by
    default), compensate what the sensors read as ``wfsbench compensate`` does with the campaign
    ``analysis`` and what ``chain`` states of them (default: :data:`BENCH_CHAIN` for the bench's
    sensors, nothing for others), and compare with the true force."""
    record = simulate_road(setup, drive, seed=seed, sensors=sensors)
    fs = record.sample_rate_hz
    channels = {name: record.channels[name] for name in MEASUREMENT_CHANNELS}
    if chain is None:
        chain = BENCH_CHAIN if sensors is None else MeasurementChain()
    source = f"road {drive.road_class} at {3.6 * drive.speed_m_s:g} km/h"
    measurement = Measurement(source, fs, channels, chain=chain)
    compensation = prepare_compensation(analysis, measurement, pressure_bar)
    blocks = list(compensation.blocks())
    model = np.concatenate([b.force_n for b in blocks])
    u95 = np.concatenate([b.u95_n for b in blocks])
    span = np.isfinite(model)
    f_wfs = channels[WFS_FORCE]
    accel = channels[HUB_ACCELERATION] - compensation.accelerometer_offset_m_s2
    four_post = analysis.knowledge.four_post
    mass_kg = four_post.wheel_mass.mass_kg if four_post is not None else analysis.wheel_mass_kg
    delay_s = compensation.filters.basis.accelerometer_delay_s
    hub = hub_acceleration_compensation(f_wfs, advance_acceleration(accel, fs, delay_s), mass_kg)
    truth = record.channels[TRUTH_CHANNEL][span]
    band = compensation.filters.basis.valid_band_hz
    traces = {
        "t_s": np.flatnonzero(span) / fs,
        "truth": truth,
        "raw": f_wfs[span],
        "hub_compensated": hub[span],
        "model_compensated": model[span],
        "u95": u95[span],
        "error_in_band": band_limited(model[span] - truth, fs, (0.0, band[1])),
    }
    return RoadValidation(
        road_class=str(drive.road_class),
        speed_km_h=3.6 * drive.speed_m_s,
        identification=compensation.filters.basis.label,
        valid_band_hz=band,
        raw=force_errors(traces["raw"], truth, fs),
        hub_compensated=force_errors(traces["hub_compensated"], truth, fs),
        model_compensated=force_errors(traces["model_compensated"], truth, fs),
        truth_rms_n=band_rms(truth, fs, ERROR_BAND_HZ),
        coverage_valid_band=coverage(traces["model_compensated"], traces["u95"], truth, fs, (0.0, band[1])),
        coverage_whole=coverage(traces["model_compensated"], traces["u95"], truth, fs, None),
        median_u95_n=float(np.median(traces["u95"])),
        noise_wfs_n=compensation.filters.basis.noise_wfs_n,
        hub_lag_ms=1e3 * delay_s,
        assumptions=tuple(a.line for a in compensation.assumptions),
        traces=traces,
    )
