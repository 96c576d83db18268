"""One master per device, one writer per campaign file (docs/protocols.md, *One master per device*):
a second ``wfsbench run`` against the devices a run holds, or into the file it writes, is refused
naming the holder before it opens, sends or reads anything, and the first run loses nothing; a
controller found moving when the bench opens is refused before anything is written to it.

The devices are the simulated controller on Modbus TCP and the WFS on a pty, served by this test
process (:func:`tests.test_campaign_cli.lab_devices`); the runs are ``wfsbench`` processes with a
bench configuration naming them as real devices. The lock directory is the test's own."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys

import pytest

from bench import locks
from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.store import open_campaign
from drivers.register_map import Command, ControllerState, WaveformCode
from tests.commands import wfsbench, wfsbench_process
from tests.sequence_texts import sequence_text
from tests.test_campaign_cli import ROOT, _bench_toml, lab_devices  # noqa: F401 - a fixture
from tests.waiting import LineReader, wait_until

#: Generous bound for a ``wfsbench`` process to start and reach its dwell on a loaded machine.
START_TIMEOUT_S = 60.0

#: A 10 s dwell, then a confirmation the test gives on the run's standard input once the second
#: runs were tried: the first holds the bench until then, however long those took on a busy machine.
LONG_DWELL = sequence_text(
    "long",
    """\
[[steps]]
type = "sine_dwell"
freq_hz = 10
amplitude_mm = 1
measure_min_s = 10

[[steps]]
type = "prompt"
id = "checked"
text = "Second runs tried"
answer = "confirm"

[[steps]]
type = "hydraulics"
level = "off"
""",
)


@pytest.fixture(autouse=True)
def lock_dir(tmp_path, monkeypatch):
    """This test's own lock directory, for itself and the processes it starts."""
    directory = tmp_path / "locks"
    monkeypatch.setenv(locks.LOCK_DIR_ENV, str(directory))
    return directory


def _popen_wfsbench(*args: str) -> subprocess.Popen:
    script = os.path.join(os.path.dirname(sys.executable), "wfsbench")
    command = [script] if os.path.exists(script) else [sys.executable, "-m", "bench.cli"]
    return subprocess.Popen(
        [*command, *args],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.validation
@pytest.mark.slow
def test_a_second_run_against_the_same_bench_is_refused_and_the_first_loses_nothing(tmp_path, lab_devices):  # noqa: F811
    server, pty = lab_devices
    sequence, config = tmp_path / "long.toml", tmp_path / "bench.toml"
    sequence.write_text(LONG_DWELL)
    config.write_text(_bench_toml(server, pty))
    first_out, second_out = tmp_path / "first.h5", tmp_path / "second.h5"
    first = _popen_wfsbench("run", str(sequence), "--out", str(first_out), "--bench", str(config))
    try:
        controller = server.bench.controller
        wait_until(
            lambda: controller.state == ControllerState.RUNNING or first.poll() is not None,
            START_TIMEOUT_S,
            "the first run's dwell",
        )
        assert first.poll() is None, first.communicate()
        holder = locks.holder_of(locks.serial_key(pty))
        assert holder is not None and holder.pid == first.pid
        assert holder.command.startswith(("wfsbench run", "cli.py run")), holder.command

        writes_before = server.writes_received
        second = wfsbench("run", str(sequence), "--out", str(second_out), "--bench", str(config))
        assert second.returncode == ExitCode.UNAVAILABLE, second.stderr
        assert second.stderr.startswith(
            f"error: {config}: wfs.device: the WFS port {pty} is in use by process {first.pid} (wfsbench run"
        ) or f"is in use by process {first.pid} (cli.py run" in second.stderr, second.stderr
        assert not second_out.exists()

        same_file = wfsbench("run", str(sequence), "--out", str(first_out), "--bench", str(config))
        assert same_file.returncode == ExitCode.UNAVAILABLE, same_file.stderr
        assert same_file.stderr.startswith(
            f"error: {first_out}: in use: being written by process {first.pid} ("
        ), same_file.stderr

        stdout, stderr = first.communicate("yes\n", timeout=START_TIMEOUT_S)
    finally:
        if first.poll() is None:
            first.send_signal(signal.SIGTERM)
            first.wait(30)
    assert first.returncode == ExitCode.INCOMPLETE, stdout + stderr
    # neither refused run connected to the controller: the first run's connection was its only one
    assert server.server.connections_accepted == 1
    assert server.writes_received > writes_before
    with open_campaign(first_out) as campaign:
        (run,) = campaign.runs
        assert run.status == "complete"
        counters = run.link_counters
        assert counters["frames_missing"] == 0, counters
        assert counters["crc_rejects"] == 0 and counters["bytes_discarded"] == 0, counters
        assert run.n_samples >= 10_000  # the 10 s dwell at 1 kHz


def test_a_controller_found_moving_is_refused_before_anything_is_written(tmp_path, lab_devices):  # noqa: F811
    """Another master (here: the test, through the model) runs an excitation: the run names the
    state and writes nothing, not even a heartbeat."""
    server, pty = lab_devices
    sequence, config = tmp_path / "long.toml", tmp_path / "bench.toml"
    sequence.write_text(LONG_DWELL)
    config.write_text(_bench_toml(server, pty))
    bench = server.bench
    with bench.lock:
        ctrl = bench.controller
        setpoints = {"waveform": WaveformCode.SINE_DWELL, "amplitude_mm": 1.0, "frequency_hz": 5.0}
        assert ctrl.write_setpoints({**setpoints, "watchdog_ms": 0}) is None
        for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH, Command.START):
            assert ctrl.command(command) is None
    run = wfsbench("run", str(sequence), "--out", str(tmp_path / "c.h5"), "--bench", str(config))
    assert run.returncode == ExitCode.UNAVAILABLE, run.stderr
    host, port = server.address
    assert run.stderr.startswith(
        f"error: {config}: the actuator controller at {host}:{port} is RUNNING: an excitation runs that"
        " this program did not start"
    ), run.stderr
    assert server.writes_received == 0
    assert ctrl.state == ControllerState.RUNNING  # untouched
    assert not (tmp_path / "c.h5").exists()


def test_wfs_monitor_and_actuator_status_are_refused_while_a_process_holds_the_device(tmp_path):
    """The lock, not the device, refuses them: nothing needs to be served at these addresses. (The
    commands run in processes of their own: a process's own locks are re-entrant.)"""
    port = "/dev/null"  # any path: the key is its real path
    with locks.holding(locks.serial_key(port), f"the WFS port {port}"):
        monitor = wfsbench_process("wfs", "monitor", "--port", port, "--duration", "1")
    assert monitor.returncode == ExitCode.UNAVAILABLE
    assert monitor.stderr.startswith(f"error: the WFS port {port} is in use by process {os.getpid()} (")
    with locks.holding(locks.tcp_key("127.0.0.1", 1502), "the actuator controller at 127.0.0.1:1502"):
        status = wfsbench_process("actuator", "status", "--port", "1502")
    assert status.returncode == ExitCode.UNAVAILABLE
    assert status.stderr.startswith(
        f"error: the actuator controller at 127.0.0.1:1502 is in use by process {os.getpid()} ("
    ), status.stderr


def test_a_lock_dies_with_its_process(tmp_path):
    """kill -9 of the holder frees the device at once: the lock file left behind holds nothing."""
    key = locks.serial_key(str(tmp_path / "port"))
    code = (
        "import sys, time; from bench import locks; "
        f"locks.acquire({key!r}, 'the WFS port'); print('held', flush=True); time.sleep(60)"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert LineReader(holder.stdout).next(60.0, "the lock held") == "held\n"
        with pytest.raises(locks.InUseError, match=rf"^the WFS port is in use by process {holder.pid} \("):
            locks.acquire(key, "the WFS port")
        holder.kill()
        holder.wait(30)
        with locks.holding(key, "the WFS port"):
            assert locks.holder_of(key) is None  # this process holds it
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait(30)


def _locked_by_another(key: str) -> bool:
    """Whether the lock file of ``key`` is locked, as another process would find it: its own open
    file and a non-blocking flock (the module's bookkeeping plays no part)."""
    fd = os.open(locks._lock_path(key), os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # closing it releases a flock it took
    return False


def test_locks_are_reentrant_within_a_process():
    """Held twice, the lock stays taken after the inner release and is free after the outer one."""
    key = "test:reentrant"
    with locks.holding(key, "a thing"):
        with locks.holding(key, "a thing"):
            assert _locked_by_another(key)
        assert _locked_by_another(key)  # the inner release did not unlock it
    assert not _locked_by_another(key)  # released by the last holder: free again
    with locks.holding(key, "a thing"):
        assert _locked_by_another(key)


@pytest.mark.parametrize("under", ["afile", "afile/locks"], ids=["a file", "under a file"])
def test_an_unusable_lock_directory_is_refused_naming_it_before_anything_opens(
    tmp_path, monkeypatch, capsys, under
):
    """``WFSBENCH_LOCK_DIR`` naming a file, or a place under one: the run says which directory and
    what to do, exit 3, and writes no campaign file (it was a traceback)."""
    (tmp_path / "afile").write_text("not a directory\n")
    monkeypatch.setenv(locks.LOCK_DIR_ENV, str(tmp_path / under))
    out = tmp_path / "c.h5"
    code = main(["run", str(ROOT / "sequences" / "files" / "smoke.toml"), "--out", str(out)])
    assert code == ExitCode.INVALID
    err = capsys.readouterr().err
    assert err.startswith(f"error: the lock directory {tmp_path / under} cannot be used (")
    assert f"set {locks.LOCK_DIR_ENV} to a directory" in err and "Traceback" not in err
    assert not out.exists()
