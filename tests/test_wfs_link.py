"""WFS reader against the simulated WFS device: in memory, over a real pty, with faults."""

from __future__ import annotations

import asyncio
import sys
import threading

import numpy as np
import pytest
import serial

from bench.models.setup import BenchSetup
from drivers.actuator import ActuatorClient
from drivers.errors import CommandOutcomeUnknownError, CommandRejectedError, LinkTimeoutError
from drivers.register_map import Command, ControllerState, InterlockFlag, WaveformCode
from drivers.setpoints import DwellSetpoint
from drivers.wfs_commands import Reply, format_command, parse_reply
from drivers.wfs_frame import FRAME_SIZE, Status
from drivers.wfs_reader import WfsReader
from drivers.wfs_stream import StreamParser
from drivers.wfs_transform import LoadProcessor
from sequences.limits import BenchLimits
from simulators.bench_sim import PACED_BLOCK_S, BenchBlock, BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.faults import ByteFaults
from simulators.plant import PlantSimulator, SensorRealism
from simulators.ports import MemoryLink, PtyLink
from simulators.wfs_device import IDENTITY, WfsDevice
from tests.waiting import async_wait_until, wait_until

#: The bound of a wait for the controller (wall clock): generous for a loaded machine, never a
#: measured time (the tapers and ramps are timed on the bench's own clock where they are tested).
DEADLINE_S = 30.0
_DWELL_REGISTERS = {
    "waveform": WaveformCode.SINE_DWELL, "amplitude_mm": 1.0, "frequency_hz": 10.0,
    "taper_in_s": 0.2, "taper_out_s": 0.2,
}  # fmt: skip


def _rig(link, *, faults=None, speed_rad_s=0.0):
    bench = SimulatedBench.paper_shaker(seed=2)
    device = WfsDevice(link, bench, seed=3, faults=faults, speed_rad_s=speed_rad_s)
    device.start()
    # unpaced, in blocks of 10 frames: the link's tests race commands against the numbering of
    # many small blocks (the unpaced default, 200 frames, would number few)
    runner = BenchRunner(bench, paced=False, block_s=PACED_BLOCK_S)
    runner.sinks.append(device)
    runner.start()
    return bench, device, runner


@pytest.fixture
def memory_rig():
    link = MemoryLink()
    _bench, device, runner = _rig(link)
    reader = WfsReader(link.open_host)
    reader.start()
    yield link, device, reader
    reader.close()
    runner.stop()
    device.stop()
    assert runner.error is None


def test_command_set_in_memory(memory_rig):
    _, device, reader = memory_rig
    assert reader.identify() == IDENTITY
    assert reader.set_rate(500) == 500
    assert reader.command("RATE?").fields == ("500",)
    with pytest.raises(CommandRejectedError, match="300 Hz not possible"):
        reader.set_rate(300)
    sub = reader.subscribe(lossless=True)
    reader.start_stream()
    with pytest.raises(CommandRejectedError, match="stop first"):
        reader.set_rate(1000)
    block = sub.read_frames(500, timeout_s=5)
    assert np.all(np.diff(block.frames["seq"].astype(np.int64)) == 1)
    assert block.frames["sample"][0] == 0
    reader.tare()
    reader.stop_stream()
    assert not device.streaming


def test_garbage_command_lines_get_an_error_reply_and_the_device_keeps_serving():
    """Raw bytes on a real pty: every bad line gets its error reply, then the device still serves."""
    link = PtyLink()
    _bench, device, runner = _rig(link)
    try:
        with serial.Serial(link.path, baudrate=921600, timeout=2) as raw:
            raw.write(b"\xff\xfe garbage\n" + b"x" * 100 + b"\n" + b"RATE fast\n" + b"IDENT\n")
            replies = [parse_reply(raw.read_until(b"\r\n")) for _ in range(4)]
        assert replies[0] == Reply(False, "?", ("unknown command",))
        assert replies[1] == Reply(False, "?", ("line too long",))
        assert not replies[2].ok and replies[2].command == "RATE"
        assert "not a whole number" in replies[2].fields[0]
        assert replies[3] == Reply(True, "IDENT", IDENTITY)
        with WfsReader.serial(link.path) as reader:
            assert reader.wait_connected(5)
            assert reader.identify() == IDENTITY
            assert reader.command("RATE?").fields == ("1000",)
    finally:
        runner.stop()
        device.stop()
        link.close()


def test_rate_changes_the_acquisition_rate_and_refuses_impossible_rates():
    link = MemoryLink()
    speed = 2 * np.pi * 5  # 5 rev/s: the wheel angle advances speed / rate per frame
    bench, device, runner = _rig(link, speed_rad_s=speed)
    reader = WfsReader(link.open_host)
    reader.start()
    try:
        assert reader.set_rate(250) == 250
        assert bench.plant.oversampling == 40  # from the 10 kHz converter
        sub = reader.subscribe(lossless=True)
        reader.start_stream()
        frames = sub.read_frames(500, timeout_s=10).frames
        reader.stop_stream()
        valid = "valid rates 100 125 200 250 400 500 625 1000 1250 Hz"
        for bad in (300, 2000, 10_000, 50, 0, -250):
            with pytest.raises(CommandRejectedError, match=f"{bad} Hz not possible,{valid}"):
                reader.set_rate(bad)
        assert reader.command("RATE?").fields == ("250",)
        assert bench.plant.oversampling == 40
    finally:
        reader.close()
        runner.stop()
        device.stop()
    step = np.diff(np.unwrap(frames["angle_rad"].astype(float)))
    assert step == pytest.approx(np.full(len(step), speed / 250), abs=2e-6)
    assert np.all(np.diff(frames["sample"].astype(np.int64)) == 1)


def test_a_block_made_before_a_rate_change_is_not_sent_after_it():
    """The interleaving a busy host meets: the bench made a block at 1000 Hz, RATE 250 is taken and
    the stream started before that block reaches the device. Its frames would go out numbered as
    250 Hz samples but hold 1000 Hz ones; the device drops the block, as an acquisition's output
    after a rate change is at the new rate only, and sends the next one."""
    link = MemoryLink()
    bench = SimulatedBench.paper_shaker(seed=2)
    device = WfsDevice(link, bench, seed=3)
    device.start()  # serves commands; no runner: the blocks are delivered here, in this order
    reader = WfsReader(link.open_host)
    reader.start()
    try:
        made_before = bench.advance(10)
        assert reader.set_rate(250) == 250
        sub = reader.subscribe(lossless=True)
        reader.start_stream()
        device.deliver(made_before)
        assert device.frames_sent == 0
        device.deliver(bench.advance(10))
        frames = sub.read_frames(10, timeout_s=10).frames
        assert device.frames_sent == 10 and frames["sample"][0] == 0
    finally:
        reader.close()
        device.stop()


def _fundamental(signal: np.ndarray, freq_hz: float, rate_hz: float) -> complex:
    """Complex amplitude at ``freq_hz`` of a record of whole cycles (exact for a sine)."""
    t = np.arange(signal.size) / rate_hz
    return 2 * np.mean(signal * np.exp(-2j * np.pi * freq_hz * t))


@pytest.mark.parametrize(
    ("setup", "settle_s"),
    [(BenchSetup.paper_shaker, 3.0), (BenchSetup.paper_quarter_car, 12.0)],
    ids=["shaker", "quarter_car"],
)
async def test_frames_carry_the_bench_channels_synchronously_during_a_dwell(setup, settle_s):
    """A 10 Hz dwell run through the Modbus controller: the WFS frames carry Fz and the bench's
    displacement, plate force and hub acceleration with the plant's exact amplitudes and phases.

    The bench runs as fast as the reader drains the WFS link, so the specimen's transient (decayed
    within ``settle_s`` of bench time) costs little wall time; the last 20 cycles are analysed.
    """
    freq_hz, amplitude_mm, cycles = 10.0, 2.0, 20
    bench = SimulatedBench(PlantSimulator(setup(), SensorRealism(seed=2)))
    link = MemoryLink()
    device = WfsDevice(link, bench, seed=3)
    device.start()
    runner = BenchRunner(bench, paced=False)
    runner.sinks.append(device)
    runner.start()
    server = ControllerServer(bench)
    host, port = await server.serve_tcp("127.0.0.1", 0)
    client = ActuatorClient.tcp(host, port, limits=BenchLimits())
    reader = WfsReader(link.open_host)
    reader.start()
    rate_hz = bench.output_rate_hz
    try:
        await client.connect()
        await client.start_heartbeat()  # the controller's watchdog is armed from power-up
        await client.hydraulics_low()
        await client.hydraulics_high()
        await client.configure(DwellSetpoint(freq_hz, amplitude_mm, taper_in_s=0.2, taper_out_s=0.2))
        await client.start()
        await async_wait_until(lambda: _state_is(client, ControllerState.RUNNING), DEADLINE_S, "the dwell")
        sub = reader.subscribe(lossless=True)
        await asyncio.to_thread(reader.start_stream)
        n = round((settle_s + cycles / freq_hz) * rate_hz)
        block = await asyncio.to_thread(sub.read_frames, n, 30.0)
        await asyncio.to_thread(reader.stop_stream)
        assert (await client.read_status()).state == ControllerState.RUNNING
        await client.stop()
    finally:
        reader.close()
        await client.close()
        await server.close()
        runner.stop()
        device.stop()
    assert runner.error is None
    frames = block.frames[-round(cycles * rate_hz / freq_hz) :]  # whole cycles, consecutive
    assert not block.gaps and not block.resyncs
    assert np.all(np.diff(frames["seq"].astype(np.int64)) == 1)
    measured = {
        ch: _fundamental(frames[ch].astype(float), freq_hz, rate_hz) for ch in ("aux0", "aux1", "aux2", "fz")
    }
    plant = bench.plant
    exact = plant.exact_response(freq_hz, amplitude_mm / 1000)
    # the base moves as the servo actuator follows the commanded amplitude
    assert abs(measured["aux0"]) == pytest.approx(
        abs(plant.base_gain(freq_hz, amplitude_mm / 1000)) * amplitude_mm / 1000, rel=0.01
    )
    # the hub accelerometer is a 2nd-order Butterworth low-pass at its bandwidth
    r = freq_hz / plant.realism.accelerometer_bandwidth_hz
    accelerometer = 1 / complex(1 - r**2, np.sqrt(2) * r)
    for channel, output, sensor in (
        ("aux1", "f_plate", 1),
        ("aux2", "a_hub", accelerometer),
        ("fz", "f_wfs", 1),
    ):
        expected = exact[output] / exact["z_base"] * sensor * measured["aux0"]
        if expected == 0:  # the shaker holds the hub: its accelerometer reads noise only
            assert abs(measured[channel]) < 0.01, channel
            continue
        ratio = measured[channel] / expected
        assert abs(ratio) == pytest.approx(1, abs=0.01), channel
        assert np.degrees(np.angle(ratio)) == pytest.approx(0, abs=0.5), channel


async def _state_is(client: ActuatorClient, state: ControllerState) -> bool:
    return (await client.read_status()).state == state


def test_overload_bits_follow_each_channels_range():
    """Ranges as the paper's Table 1: Fx, Fz 24 kN, Fy 15 kN, Mx, Mz 4.5 kN m, My 7.2 kN m."""
    bench = SimulatedBench.paper_shaker(seed=2)
    link = MemoryLink()
    device = WfsDevice(link, bench, noise_n=0.0)
    device.crosstalk = np.array([0.0, 1.0, 0.3, 0.3, 0.0])  # Fy = Fz, Mx = My = 0.3 m x Fz
    device.execute("START", [])
    fz = np.array([16_000.0, -16_000.0, 14_000.0])  # Fy beyond 15 kN, then within
    zeros = np.zeros(len(fz))
    channels = {"fz_wfs_n": fz, "z_base_m": zeros, "f_plate_n": zeros, "a_hub_m_s2": zeros}
    device.deliver(BenchBlock(0.0, 1000.0, channels))
    status = StreamParser().feed(link.open_host().read(3 * FRAME_SIZE)).frames["status"]
    # 16 kN: Fy (15 kN) and Mx (4.8 > 4.5 kN m) overload, Fz (24 kN) and My (7.2 kN m) do not
    assert [Status(int(s)) for s in status] == [
        Status.OVERLOAD_FY | Status.OVERLOAD_MX,
        Status.OVERLOAD_FY | Status.OVERLOAD_MX,
        Status(0),
    ]


def test_aux_overload_and_adc_fault_bits():
    """Aux ranges: 50 mm, 50 kN, 490 m/s^2 (50 g); a conversion that yields no number is an ADC fault."""
    bench = SimulatedBench.paper_shaker(seed=2)
    link = MemoryLink()
    device = WfsDevice(link, bench, noise_n=0.0)
    device.execute("START", [])
    z = np.array([0.049, -0.051, 0.0, 0.0, 0.0, 0.0])
    plate = np.array([0.0, 0.0, 50_001.0, 0.0, 0.0, 0.0])
    hub = np.array([0.0, 0.0, 0.0, -491.0, 0.0, np.nan])
    fz = np.array([0.0, 0.0, 0.0, 0.0, np.nan, 0.0])
    channels = {"fz_wfs_n": fz, "z_base_m": z, "f_plate_n": plate, "a_hub_m_s2": hub}
    device.deliver(BenchBlock(0.0, 1000.0, channels))
    status = StreamParser().feed(link.open_host().read(6 * FRAME_SIZE)).frames["status"]
    aux, fault = Status.OVERLOAD_AUX, Status.ADC_FAULT
    assert [Status(int(s)) for s in status] == [Status(0), aux, aux, aux, fault, fault]


def test_no_reply_is_a_timeout(memory_rig):
    _, device, reader = memory_rig
    device.stop()  # the command thread no longer answers
    with pytest.raises(LinkTimeoutError):
        reader.command("IDENT", timeout_s=0.1, attempts=2)


@pytest.mark.parametrize("name", ["START", "TARE"])
def test_start_and_tare_are_never_resent(memory_rig, name):
    link, device, reader = memory_rig
    device.stop()  # the command thread no longer answers; what the host sends stays on the link
    with pytest.raises(CommandOutcomeUnknownError):
        reader.command(name, timeout_s=0.1, attempts=3)
    sent = link.device_read(4096, 0.5)
    assert sent == format_command(name)


def test_idempotent_commands_are_resent_on_timeout(memory_rig):
    link, device, reader = memory_rig
    device.stop()
    with pytest.raises(LinkTimeoutError) as err:
        reader.command("IDENT", timeout_s=0.1, attempts=2)
    assert not isinstance(err.value, CommandOutcomeUnknownError)
    assert link.device_read(4096, 0.5) == 2 * format_command("IDENT")


@pytest.mark.slow
def test_faults_every_loss_counted_reader_never_stops_and_reconnect_resumes():
    link = MemoryLink()
    faults = ByteFaults(seed=11, bit_error_rate=1e-3, drop_rate=1e-4, duplicate_rate=1e-4, garbage_rate=1e-4)
    _bench, device, runner = _rig(link, faults=faults)
    reader = WfsReader(link.open_host)
    reader.start()
    try:
        sub = reader.subscribe(lossless=True)
        reader.start_stream()
        got = sub.read_frames(5000, timeout_s=20)
        # stall: 200 frames are not sent, then the stream resumes with a gap
        device.stall(200)
        got2 = sub.read_frames(3000, timeout_s=20)
        stalled = device.frames_unsent
        # disconnect and reconnect: the reader reopens the link and the stream resumes
        device.disconnect()
        wait_until(lambda: not reader.wait_connected(0), 5, "the reader to see the link drop")
        # the bench goes on while the link is down, losing frames (on a busy machine the reader
        # may see the drop before the bench has produced the next block)
        wait_until(lambda: device.frames_unsent > stalled, 10, "frames produced while the link is down")
        device.reconnect()
        assert reader.wait_connected(5)
        got3 = sub.read_frames(3000, timeout_s=20)
        assert reader.running
        sub.close()
        reader.command("STOP")
        counters = reader.counters
    finally:
        reader.close()
        runner.stop()
        device.stop()
    seqs = np.concatenate([b.frames["seq"] for b in (got, got2, got3)]).astype(np.int64)
    assert np.all(np.diff(seqs) > 0)
    span = int(seqs[-1] - seqs[0] + 1)
    # consecutive blocks: every frame between the first and the last delivered one is either
    # delivered or marked missing by a gap
    marked = sum(g.missing for b in (got, got2, got3) for g in b.gaps)
    assert marked == span - len(seqs) > 0
    assert counters.frames_missing >= marked
    assert counters.crc_rejects > 0
    assert counters.reconnects == 1
    assert stalled == 200 < device.frames_unsent  # the stall and the disconnect really lost frames
    assert any(g.missing >= 200 for g in got2.gaps)


def test_a_host_that_stops_reading_never_freezes_the_bench_and_the_watchdog_stops_it():
    link = MemoryLink()
    bench, device, runner = _rig(link)
    host = link.open_host()
    ctrl = bench.controller
    parser = StreamParser()
    try:
        with bench.lock:
            assert ctrl.write_setpoints({**_DWELL_REGISTERS, "watchdog_ms": 300, "heartbeat": 1}) is None
            for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH, Command.START):
                assert ctrl.command(command) is None
        device.execute("START", [])
        # the host reads and beats until it has seen 2000 frames, then dies: no reads, no beats
        beat = 1
        while parser.counters.frames_ok < 2000:
            parser.feed(host.read(4096))
            beat += 1
            with bench.lock:
                ctrl.write_setpoints({"heartbeat": beat})
        assert ctrl.state == ControllerState.RUNNING
        # the device cannot write: it drops frames (once it has waited its 1 s for the host), and
        # the bench, never held up by it, keeps advancing in real time, so the watchdog fires and
        # the taper completes
        wait_until(lambda: ctrl.state == ControllerState.INTERLOCK, 5.0, "the watchdog stop")
        assert ctrl.flags == InterlockFlag.WATCHDOG
        wait_until(lambda: device.frames_dropped > 0, 5.0, "frames dropped")
        # the host comes back: the stream resumes and the sequence counter shows the loss
        wait_until(lambda: parser.feed(host.read(4096)).gaps or parser.counters.gaps, 5.0, "a gap")
        assert parser.counters.frames_missing > 0
    finally:
        runner.stop()
        device.stop()
    assert runner.error is None


def test_stream_over_a_real_pseudo_terminal_with_rotation():
    link = PtyLink()
    speed = 2 * np.pi * 5  # 5 rev/s
    _bench, device, runner = _rig(link, speed_rad_s=speed)
    reader = WfsReader.serial(link.path, baudrate=921600)
    reader.start()
    try:
        assert reader.wait_connected(5)
        assert reader.identify() == IDENTITY
        sub = reader.subscribe(lossless=True)
        reader.start_stream()
        block = sub.read_frames(3000, timeout_s=20)
        reader.stop_stream()
        counters = reader.counters
    finally:
        reader.close()
        runner.stop()
        device.stop()
        link.close()
    frames = block.frames
    assert counters.frames_missing == 0 and counters.crc_rejects == 0
    assert np.all(np.diff(frames["seq"].astype(np.int64)) == 1)
    # the angle turns; in the sensor frame Fz leaks into Fx, in the wheel frame it does not
    assert np.ptp(frames["angle_rad"]) > 6
    wheel = LoadProcessor().wheel_loads(frames)
    fz = wheel[:, 2]
    assert np.abs(frames["fx"]).max() > 0.5 * np.abs(fz).max()
    assert np.abs(wheel[:, 0]).max() < 0.01 * np.abs(fz).max() + 10


def test_reader_exposes_its_thread_id_only_while_running():
    """CPU accounting (benchmarks) goes through a public id, never the private thread."""
    reader = WfsReader(MemoryLink().open_host)
    assert reader.thread_id is None
    with reader:
        wait_until(lambda: reader.thread_id is not None, 2.0, "reader thread start")
        assert reader.thread_id != threading.get_native_id()  # not the caller's thread
    assert reader.thread_id is None


def test_tare_zeroes_the_loads_at_the_present_load():
    """The actuator holds 5 mm (about 1.9 kN on the tyre); after TARE every load channel reads zero.
    No host beats here, so the controller's watchdog (armed at power-up, in wall-clock time) is off:
    on a busy machine the 6 s of bench time outlast its 1.5 s, and its taper to rest moved the load
    under the tare."""
    link = MemoryLink()
    bench, device, runner = _rig(link)
    reader = WfsReader(link.open_host)
    reader.start()
    try:
        with bench.lock:
            hold = {"waveform": WaveformCode.STATIC, "mean_mm": 5.0, "watchdog_ms": 0}
            assert bench.controller.write_setpoints(hold) is None
            for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH, Command.START):
                assert bench.controller.command(command) is None
        sub = reader.subscribe(lossless=True, max_frames=10**9)  # never full within this test
        reader.start_stream()
        before = sub.read_frames(3000, timeout_s=20).frames[-500:]  # the 0.5 s mean ramp is over
        reader.tare()
        after = sub.read_frames(3000, timeout_s=20).frames
        sub.close()
        reader.stop_stream()
        with bench.lock:
            assert bench.controller.state is ControllerState.RUNNING  # held throughout
    finally:
        reader.close()
        runner.stop()
        device.stop()
    assert not np.any(before["status"] & Status.TARED)
    assert np.mean(before["fz"]) > 1500
    tared = after[(after["status"] & Status.TARED) != 0]
    assert len(tared) > 2000
    # the tare is the mean of 100 samples with about 1 N of noise: its error is about 0.1 N
    for channel in ("fx", "fy", "fz", "mx", "my", "mz"):
        assert abs(np.mean(tared[channel])) < 1.0, channel


def test_a_device_restart_is_a_resync_for_the_reader():
    link = MemoryLink()
    _bench, device, runner = _rig(link)
    reader = WfsReader(link.open_host)
    reader.start()
    try:
        sub = reader.subscribe(lossless=True, max_frames=10**9)
        reader.start_stream()
        first = sub.read_frames(500, timeout_s=20)
        device.restart()  # a power cycle: streaming stops, the counters start over
        reader.start_stream()
        second = sub.read_frames(500, timeout_s=20)
        sub.close()
        reader.stop_stream()
    finally:
        reader.close()
        runner.stop()
        device.stop()
    assert set(first.frames["boot"].tolist()) == {1}
    assert not first.resyncs and not second.gaps
    [resync] = second.resyncs
    assert (resync.last_boot, resync.boot, resync.seq) == (1, 2, 0)
    restarted = second.frames[resync.index :]
    assert restarted["sample"][0] == 0 and np.all(np.diff(restarted["seq"].astype(np.int64)) == 1)


def test_start_restarts_the_sample_clock_while_the_bench_numbers_frames():
    """START from the command side races the bench thread numbering a block: the sample clock must
    restart at exactly 0 every time (the counters change under one lock), never continue from the
    block that was being numbered."""
    link = MemoryLink()
    _bench, device, runner = _rig(link)
    host = link.open_host()
    parser = StreamParser()
    frames: list[np.ndarray] = []
    done = threading.Event()

    def drain() -> None:
        while not done.is_set():
            frames.append(parser.feed(host.read(16 * FRAME_SIZE)).frames)

    drainer = threading.Thread(target=drain)
    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible: the race shows if it exists
    rng = np.random.default_rng(5)
    try:
        device.execute("START", [])
        drainer.start()
        for _ in range(500):
            device.execute("START", [])
            # let the bench number a few frames before the next START, at a random instant
            target = parser.counters.frames_ok + int(rng.integers(5, 60))
            wait_until(lambda t=target: parser.counters.frames_ok >= t, 10, "frames after START")
    finally:
        sys.setswitchinterval(switch)
        runner.stop()
        device.stop()
        done.set()
        drainer.join(5)
    sample = np.concatenate(frames)["sample"].astype(np.int64)
    back = np.flatnonzero(np.diff(sample) != 1) + 1
    assert len(back) > 400  # the restarts really happened while frames flowed
    assert np.all(sample[back] == 0)
