"""The controller's sync outputs in the WFS frames, and the rotating wheel, end to end."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

from drivers.actuator import ActuatorClient
from drivers.setpoints import DwellSetpoint
from drivers.wfs_frame import Status
from drivers.wfs_reader import SampleBlock, Subscription, WfsReader
from drivers.wfs_transform import LoadProcessor
from sequences.limits import BenchLimits
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.function_generator import AMPLITUDE_HOLD, EXCITATION_ACTIVE, sync_flags
from simulators.plant.excitation import SineDwell, Sweep
from simulators.plant.sensors import Decimator
from simulators.ports import MemoryLink
from simulators.wfs_device import DigitalInputs, WfsDevice

RATE_HZ = 10_000  # the converter rate


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, length)`` of every run of True in ``mask``."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(s), int(e - s)) for s, e in zip(starts, ends, strict=True)]


def test_sync_flags_of_a_dwell_and_a_sweep():
    t = np.arange(round(5 * RATE_HZ)) / RATE_HZ - 0.5
    dwell = SineDwell(10.0, 1e-3, hold_s=2.0, taper_in_s=0.5, taper_out_s=0.75)
    flags = sync_flags(t, dwell)
    assert _runs((flags & EXCITATION_ACTIVE) != 0) == [(5000, 32_500)]
    assert _runs((flags & AMPLITUDE_HOLD) != 0) == [(10_000, 20_000)]
    sweep = Sweep(1.0, 10.0, 3.0, 1e-3, taper_in_s=0.25, taper_out_s=0.5)
    assert _runs((sync_flags(t, sweep) & AMPLITUDE_HOLD) != 0) == [(7500, 22_500)]
    # stopped early 1.5 s into the excitation: the hold ends there, the excitation a taper later
    stopped = sync_flags(t, dwell, stop_s=1.5, taper_out_s=0.75)
    assert _runs((stopped & AMPLITUDE_HOLD) != 0) == [(10_000, 10_000)]
    assert _runs((stopped & EXCITATION_ACTIVE) != 0) == [(5000, 22_500)]


@pytest.mark.parametrize("edge", [12_345, 12_340, 99])
def test_a_sync_edge_lines_up_with_the_analog_channels_through_the_anti_alias_filter(edge):
    """A step at converter sample ``edge`` on a digital input and on an analog channel (through the
    acquisition's linear-phase FIR, delay 8 output samples): the flag rises at the output sample
    where the filtered step crosses half its height (+/- 1 sample)."""
    factor, n_out = 10, 3000
    step = (np.arange(n_out * factor) >= edge).astype(float)
    flags = step.astype(np.uint8)
    decimator, inputs = Decimator(factor, 1), DigitalInputs()
    analog, digital = [], []
    for lo in range(0, n_out * factor, 100 * factor):  # in blocks, as the bench delivers them
        analog.append(decimator(step[None, lo : lo + 100 * factor])[0])
        digital.append(inputs.sample(flags[lo : lo + 100 * factor], 100, decimator.latency_samples))
    analog_out, digital_out = np.concatenate(analog), np.concatenate(digital)
    crossing = int(np.argmax(analog_out >= 0.5))
    rise = int(np.argmax(digital_out != 0))
    assert abs(rise - crossing) <= 1
    assert np.all(digital_out[rise:] == 1) and not np.any(digital_out[:rise])


def _until_excitation_ends(sub: Subscription, timeout_s: float) -> SampleBlock:
    """Blocks up to 100 frames after the excitation-active bit has risen and fallen again, within
    ``timeout_s`` (or until the subscription is closed)."""
    deadline = time.monotonic() + timeout_s
    parts: list[np.ndarray] = []
    seen_active, after = False, 0
    while after < 100:
        block = sub.get(max(deadline - time.monotonic(), 0.0))
        assert block is not None, f"the excitation did not end within {timeout_s} s"
        assert not block.gaps and not block.resyncs
        parts.append(block.frames)
        active = (block.frames["status"] & Status.EXCITATION_ACTIVE) != 0
        seen_active |= bool(active.any())
        if seen_active and not active[-1]:
            after += len(block)
    return SampleBlock(np.concatenate(parts))


def _fit(signal: np.ndarray, freq_hz: float, rate_hz: float) -> complex:
    """Least-squares ``a + i b`` of ``signal ~ a sin(w s) + b cos(w s) + c``, ``s`` from the first sample:
    its modulus is the amplitude and its angle the phase of the sine at that sample."""
    s = np.arange(len(signal)) / rate_hz
    w = 2 * np.pi * freq_hz
    basis = np.column_stack([np.sin(w * s), np.cos(w * s), np.ones_like(s)])
    (a, b, _), *_ = np.linalg.lstsq(basis, signal, rcond=None)
    return complex(a, b)


async def test_a_modbus_dwell_shows_its_hold_in_the_frames_and_the_wheel_loads_match_the_plant():
    """A 40 Hz, 1 mm dwell (0.5 s tapers, 3 s hold) started over Modbus while the wheel turns at
    3 rev/s: the hold bit is set for exactly 3 s of samples (+/- 1), both bits rise where the
    displacement's envelope says the taper begins and the hold starts, and the loads rotated to the
    wheel frame carry the plant's WFS force."""
    freq_hz, amplitude_mm, hold_s, taper_s = 40.0, 1.0, 3.0, 0.5
    bench = SimulatedBench.paper_shaker(seed=2)
    link = MemoryLink()
    device = WfsDevice(link, bench, seed=3, speed_rad_s=2 * np.pi * 3)
    runner = BenchRunner(bench, paced=False)
    runner.sinks.append(device)
    device.start()
    runner.start()
    server = ControllerServer(bench)
    host, port = await server.serve_tcp("127.0.0.1", 0)
    client = ActuatorClient.tcp(host, port, limits=BenchLimits())
    reader = WfsReader(link.open_host)
    reader.start()
    sub = reader.subscribe(lossless=True, max_frames=10**9)  # the reader never waits for the test
    rate_hz = bench.output_rate_hz
    try:
        await asyncio.to_thread(reader.start_stream)
        collecting = asyncio.create_task(asyncio.to_thread(_until_excitation_ends, sub, 60.0))
        await client.connect()
        await client.start_heartbeat()
        await client.hydraulics_low()
        await client.hydraulics_high()
        await client.configure(DwellSetpoint(freq_hz, amplitude_mm, hold_s, taper_s, taper_s))
        await client.start()
        frames = (await collecting).frames
        sub.close()
        await asyncio.to_thread(reader.stop_stream)
        await client.stop_heartbeat()
    finally:
        sub.close()  # ends the collecting thread if the test failed before
        reader.close()
        await client.close()
        await server.close()
        runner.stop()
        device.stop()
    assert runner.error is None
    [(active_at, active_n)] = _runs((frames["status"] & Status.EXCITATION_ACTIVE) != 0)
    [(hold_at, hold_n)] = _runs((frames["status"] & Status.AMPLITUDE_HOLD) != 0)
    assert abs(hold_n - hold_s * rate_hz) <= 1
    assert abs(active_n - (hold_s + 2 * taper_s) * rate_hz) <= 1
    assert abs(hold_at - active_at - taper_s * rate_hz) <= 1
    # the displacement's phase from the hold bit's edge: the dwell's sine starts at phase 0 and
    # 0.5 s (20 whole cycles) before the hold, so only the servo's phase lag remains, plus the
    # up to 1 output sample by which the flag rises after the excitation's start (14.4 deg at 40 Hz);
    # a flag misaligned by the filter's 8 samples would be 115 deg off
    hold = frames[hold_at : hold_at + hold_n]
    z = _fit(hold["aux0"].astype(float), freq_hz, rate_hz)
    servo = bench.plant.base_gain(freq_hz, amplitude_mm / 1000)
    lead_deg = np.degrees(np.angle(z / servo))
    assert -1.0 < lead_deg < 360 * freq_hz / rate_hz + 1.0
    assert abs(z) == pytest.approx(abs(servo) * amplitude_mm / 1000, rel=0.01)
    # the last second of the hold (40 cycles, the tyre's transient gone): the loads in the sensor
    # frame spin with the wheel; rotated back, Fz is the plant's WFS force and Fx its crosstalk
    last = hold[-round(rate_hz) :]
    assert np.ptp(np.unwrap(last["angle_rad"].astype(float))) == pytest.approx(2 * np.pi * 3, rel=0.01)
    wheel = LoadProcessor().wheel_loads(last)
    exact = bench.plant.exact_response(freq_hz, amplitude_mm / 1000)
    expected_fz = exact["f_wfs"] / exact["z_base"] * _fit(last["aux0"].astype(float), freq_hz, rate_hz)
    ratio = _fit(wheel[:, 2], freq_hz, rate_hz) / expected_fz
    assert abs(ratio) == pytest.approx(1, abs=0.01)
    assert np.degrees(np.angle(ratio)) == pytest.approx(0, abs=0.5)
    crosstalk_fx = wheel[:, 0] - device.crosstalk[0] * wheel[:, 2]
    assert np.std(crosstalk_fx) < 1.5  # the channels' 1 N rms noise
    assert np.std(last["fx"]) > 0.3 * np.std(wheel[:, 2])  # in the sensor frame Fz leaks into Fx
