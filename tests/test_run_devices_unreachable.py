"""A device the configuration names cannot be reached: ``wfsbench run`` says which, naming the
configuration file, its keys and the address tried (exit code 2); the library log lines (pymodbus's
"Failed to connect ...") go to ``FILE.log`` beside the campaign file, not into the terminal."""

from __future__ import annotations

import socket

from bench.cli import EXIT_LINK
from tests.test_campaign_cli import SMOKE, _bench_toml, lab_devices, wfsbench  # noqa: F401 - a fixture
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
    assert run.returncode == EXIT_LINK, run.stdout + run.stderr
    first, *rest = run.stderr.splitlines()
    assert first.startswith(
        f"error: {config}: actuator.host, actuator.port: cannot reach the actuator controller at"
        f" 127.0.0.1:{port}: "
    ), run.stderr
    assert rest == [f"warnings of the links and libraries: {out}.log"]
    assert "Failed to connect" in (tmp_path / "nodev.h5.log").read_text()  # pymodbus's line, in the log
    assert not out.exists()


def test_a_wfs_port_that_does_not_open_is_named_by_its_key(tmp_path, lab_devices):  # noqa: F811
    server, _ = lab_devices
    config, answers, out = tmp_path / "lab.toml", tmp_path / "ok.toml", tmp_path / "nowfs.h5"
    missing = tmp_path / "no-such-pty"
    config.write_text(_bench_toml(server, str(missing)))
    answers.write_text(SMOKE_ANSWERS)
    run = wfsbench("run", str(SMOKE), "--bench", str(config), "--out", str(out), "--answers", str(answers))
    assert run.returncode == EXIT_LINK, run.stdout + run.stderr
    assert run.stderr.startswith(
        f"error: {config}: wfs.device: cannot reach the WFS acquisition at {missing}: "
    ), run.stderr
    assert not out.exists()
