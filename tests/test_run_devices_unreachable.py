"""A device the configuration names cannot be reached: ``wfsbench run`` says which, naming the
configuration file, its keys and the address tried (exit code 2), and leaves no file behind: neither
the campaign file nor ``FILE.log`` (the library's lines there, pymodbus's "Failed to connect ...",
would only repeat the error)."""

from __future__ import annotations

import socket

from bench.cli.exit_codes import ExitCode
from tests.commands import wfsbench
from tests.test_campaign_cli import SMOKE, _bench_toml, lab_devices  # noqa: F401 - a fixture
from tests.test_run_unattended import SMOKE_ANSWERS


def _closed_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on (bound, then released)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_an_actuator_controller_nobody_serves_is_named_by_its_keys_and_address(tmp_path):
    port = _closed_port()
    config, answers, out = tmp_path / "lab.toml", tmp_path / "ok.toml", tmp_path / "nodev.h5"
    config.write_text(
        f'kind = "shaker"\n[actuator]\ntransport = "tcp"\nhost = "127.0.0.1"\nport = {port}\n'
        f'[wfs]\ntransport = "serial"\ndevice = "{tmp_path / "wfs"}"\n'
    )
    answers.write_text(SMOKE_ANSWERS)
    run = wfsbench("run", str(SMOKE), "--bench", str(config), "--out", str(out), "--answers", str(answers))
    assert run.returncode == ExitCode.UNAVAILABLE, run.stdout + run.stderr
    first, *rest = run.stderr.splitlines()
    assert first.startswith(
        f"error: {config}: actuator.host, actuator.port: cannot reach the actuator controller at"
        f" 127.0.0.1:{port}: "
    ), run.stderr
    assert rest == []
    assert not out.exists() and not (tmp_path / "nodev.h5.log").exists()


def test_a_wfs_port_that_does_not_open_is_named_by_its_key(tmp_path, lab_devices):  # noqa: F811
    server, _ = lab_devices
    config, answers, out = tmp_path / "lab.toml", tmp_path / "ok.toml", tmp_path / "nowfs.h5"
    missing = tmp_path / "no-such-pty"
    config.write_text(_bench_toml(server, str(missing)))
    answers.write_text(SMOKE_ANSWERS)
    run = wfsbench("run", str(SMOKE), "--bench", str(config), "--out", str(out), "--answers", str(answers))
    assert run.returncode == ExitCode.UNAVAILABLE, run.stdout + run.stderr
    assert run.stderr.startswith(
        f"error: {config}: wfs.device: cannot reach the WFS acquisition at {missing}: "
    ), run.stderr
    assert not out.exists() and not (tmp_path / "nowfs.h5.log").exists()
