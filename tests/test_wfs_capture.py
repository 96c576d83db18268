"""Triggered capture: the message codec, the parser between frames, the device's trigger, and a
hammer test end to end over a real pty analysed by the hammer analysis."""

from __future__ import annotations

import numpy as np
import pytest

from bench.analysis.records import HammerRecord
from bench.analysis.runs import analyse_hammer
from bench.models.setup import BenchKind, BenchSetup
from drivers.errors import CommandRejectedError, LinkTimeoutError
from drivers.wfs_capture import HEADER_SIZE, Capture, crc16, decode_capture, encode_capture, message_size
from drivers.wfs_commands import Reply
from drivers.wfs_frame import crc16_rows, encode, new_frames
from drivers.wfs_reader import WfsReader
from drivers.wfs_stream import StreamParser
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.capture_trigger import BASELINE_SAMPLES, CaptureTrigger
from simulators.plant import PlantSimulator, SensorRealism
from simulators.ports import MemoryLink, PtyLink
from simulators.wfs_device import WfsDevice
from simulators.world import SimulatedWorld


def a_capture(n: int = 300, pre: int = 40) -> Capture:
    rng = np.random.default_rng(5)
    samples = rng.normal(0, 100, n).astype(np.float32).astype(float)
    return Capture(samples, 10_000.0, pre, 500.0, -3.25)


def frames(first_seq: int, n: int) -> bytes:
    block = new_frames(n)
    block["seq"] = first_seq + np.arange(n)
    block["fz"] = np.arange(n)
    return encode(block)


def test_codec_round_trip_and_its_crc_is_the_frames():
    capture = a_capture()
    message = encode_capture(capture)
    assert len(message) == message_size(300) == HEADER_SIZE + 4 * 300 + 2
    assert message[:2] == bytes([0x3C, 0xC3])
    consumed, decoded = decode_capture(message)
    assert consumed == len(message)
    np.testing.assert_array_equal(decoded.samples_n, capture.samples_n)
    assert (decoded.rate_hz, decoded.pre_trigger_samples) == (10_000.0, 40)
    assert (decoded.trigger_level_n, decoded.baseline_n) == (500.0, -3.25)
    assert decoded.t_s[40] == 0.0 and decoded.t_s[0] == pytest.approx(-0.004)
    head = np.frombuffer(message[2:22], dtype=np.uint8).reshape(1, -1)
    assert [crc16(message[2:22])] == crc16_rows(head).tolist()  # the frames' CRC-16/CCITT-FALSE
    for cut in (1, HEADER_SIZE - 1, HEADER_SIZE, len(message) - 1):
        assert decode_capture(message[:cut]) == (0, None)  # incomplete: wait


@pytest.mark.parametrize("where", [5, HEADER_SIZE + 17, -1])
def test_a_corrupt_capture_is_refused(where):
    message = bytearray(encode_capture(a_capture()))
    message[where] ^= 0x40
    assert decode_capture(bytes(message)) == (1, None)


def test_the_parser_finds_captures_between_frames_in_any_chunking():
    reply = Reply(True, "CAPTURE", ("300", "40", "10000")).encode()
    stream = frames(0, 20) + reply + frames(20, 5) + encode_capture(a_capture()) + frames(25, 30)
    rng = np.random.default_rng(1)
    cuts = np.sort(rng.choice(np.arange(1, len(stream)), 40, replace=False))
    parser = StreamParser()
    bounds = zip(np.r_[0, cuts], np.r_[cuts, len(stream)], strict=True)
    results = [parser.feed(stream[a:b]) for a, b in bounds]
    seq = np.concatenate([r.frames["seq"] for r in results])
    np.testing.assert_array_equal(seq, np.arange(55))
    captures = [c for r in results for c in r.captures]
    assert len(captures) == 1 and parser.counters.captures == 1
    np.testing.assert_array_equal(captures[0].samples_n, a_capture().samples_n)
    assert [r for res in results for r in res.replies] == [Reply(True, "CAPTURE", ("300", "40", "10000"))]
    assert parser.counters.gaps == 0 and parser.counters.bytes_discarded == 0


def test_a_damaged_capture_is_skipped_and_the_frames_after_it_are_kept():
    damaged = bytearray(encode_capture(a_capture()))
    damaged[HEADER_SIZE + 100] ^= 0xFF
    parser = StreamParser()
    result = parser.feed(frames(0, 10) + bytes(damaged) + frames(10, 10))
    np.testing.assert_array_equal(result.frames["seq"], np.arange(20))
    assert result.captures == [] and parser.counters.bytes_discarded == len(damaged)


def test_trigger_uses_the_history_for_baseline_and_pre_trigger():
    history = np.full(500, 7.0)
    trigger = CaptureTrigger(
        history, rate_hz=10_000.0, trigger_level_n=50.0, pre_trigger_samples=200, length_samples=300
    )
    assert trigger.baseline_n == 7.0
    quiet = np.full(1000, 7.0) + np.linspace(-40, 40, 1000)  # stays within the level
    assert trigger.feed(quiet) is None
    blow = np.full(400, 7.0)
    blow[30:] += 60.0
    capture = trigger.feed(blow)
    assert capture is not None and capture.pre_trigger_samples == 200 and len(capture.samples_n) == 300
    assert capture.samples_n[199] == 7.0 and capture.samples_n[200] == 67.0
    np.testing.assert_array_equal(capture.samples_n[:170], quiet[-170:])


def test_trigger_without_history_waits_for_its_baseline():
    trigger = CaptureTrigger(
        np.zeros(0), rate_hz=10_000.0, trigger_level_n=5.0, pre_trigger_samples=10, length_samples=20
    )
    first = np.zeros(BASELINE_SAMPLES + 20)
    first[50] = 100.0  # inside the baseline window: not a trigger, only a (slightly) raised baseline
    assert trigger.feed(first) is None and trigger.baseline_n == pytest.approx(1.0)
    later = np.zeros(40)
    later[5] = 100.0
    capture = trigger.feed(later)
    assert capture is not None and capture.samples_n[10] == 100.0


def _hammer_rig(link):
    """The shaker with the wheel removed, its acquisition on ``link``, running in real time."""
    bench = SimulatedBench(PlantSimulator(BenchSetup.paper_free_run(), SensorRealism(seed=21)))
    world = SimulatedWorld(bench, specimen_mounted=False)
    device = WfsDevice(link, bench, seed=22)
    device.start()
    runner = BenchRunner(bench, paced=False)
    runner.sinks.append(device)
    runner.start()
    return world, device, runner


def test_capture_refusals_and_timeout_in_memory():
    link = MemoryLink()
    world, device, runner = _hammer_rig(link)
    try:
        with WfsReader(link.open_host) as reader:
            with pytest.raises(CommandRejectedError, match=r"pre <= 0\.99 s"):
                reader.arm_capture(500.0, 2.0, 3.0)
            with pytest.raises(CommandRejectedError, match="beyond 10 s"):
                reader.arm_capture(500.0, 0.01, 20.0)
            with pytest.raises(CommandRejectedError, match="not possible"):
                reader.arm_capture(-5.0, 0.01, 0.05)
            with pytest.raises(LinkTimeoutError, match="no triggered capture"):
                reader.capture(5000.0, 0.005, 0.05, timeout_s=0.3)  # armed, but nobody strikes
    finally:
        runner.stop()
        device.stop()
    assert runner.error is None and world.bench.plant.setup.kind is BenchKind.FREE_RUN


def test_hammer_test_over_a_real_pty_gives_the_sensor_eigenfrequency_and_damping():
    """Arm, strike, receive the 10 kHz block over the pty; the hammer analysis on it finds the
    simulated sensor's eigenfrequency within 0.5 % and its damping ratio within 10 %."""
    link = PtyLink()
    world, device, runner = _hammer_rig(link)
    try:
        with WfsReader.serial(link.path) as reader:
            assert reader.wait_connected(5)
            with reader.subscribe(lossless=True) as frames:
                reader.start_stream()
                frames.read_frames(50, timeout_s=5)  # 50 ms converted: the history holds the baseline
            samples, pre = reader.arm_capture(500.0, 0.005, 0.1)
            assert (samples, pre) == (1000, 50)
            world.strike_hammer(3000.0, 1.5e-4)
            capture = reader.wait_capture(timeout_s=10)
            reader.stop_stream()
    finally:
        runner.stop()
        device.stop()
        link.close()
    assert runner.error is None
    assert (capture.rate_hz, len(capture.samples_n), capture.pre_trigger_samples) == (10_000.0, 1000, 50)
    assert np.all(np.abs(capture.samples_n[:50] - capture.baseline_n) <= 500.0)  # quiet before the trigger
    assert abs(capture.samples_n[50] - capture.baseline_n) > 500.0
    sensor = world.setup.sensor
    result = analyse_hammer(
        HammerRecord(capture.rate_hz, {"fz_wfs_n": capture.samples_n}), sensor_mass_kg=sensor.mass_kg
    )
    print(
        f"\n  hammer over pty: {result.eigenfrequency_hz:.1f} Hz (simulated {sensor.eigenfrequency_hz:g}), "
        f"zeta {result.damping_ratio_log_decrement:.4f} / {result.damping_ratio_half_power:.4f} "
        f"(decrement / half power; simulated {sensor.damping_ratio:g})"
    )
    assert result.eigenfrequency_hz == pytest.approx(sensor.eigenfrequency_hz, rel=0.005)
    assert result.damping_ratio_log_decrement == pytest.approx(sensor.damping_ratio, rel=0.10)
    assert result.damping_ratio_half_power == pytest.approx(sensor.damping_ratio, rel=0.10)
