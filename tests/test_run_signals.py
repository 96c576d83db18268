"""SIGTERM and SIGHUP during ``wfsbench run`` are handled as Ctrl-C is: the excitation under way is
tapered out, the campaign file is closed with the run marked ``aborted`` and the signal as its
reason, and the command exits with code 1. SIGTERM is sent to a real subprocess; the hang-up is the
kernel's own, the command's controlling terminal (a pseudo-terminal) closing under it."""

from __future__ import annotations

import os
import pty
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest

from bench.cli.exit_codes import ExitCode
from bench.store import open_campaign
from tests.test_campaign_cli import H5DUMP, ROOT
from tests.test_run_unattended import RUN_ID, long_dwell_command
from tests.waiting import LineReader

DEADLINE_S = 120.0  # wall clock, a timeout only


def _command(tmp_path: Path) -> tuple[list[str], Path]:
    return long_dwell_command(tmp_path, taper_out_s=0.5)


def _assert_tapered_and_aborted(out: Path, reason: str) -> None:
    dump = subprocess.run(
        [H5DUMP, "-a", f"/runs/{RUN_ID}/status", str(out)], capture_output=True, text=True, check=False
    )
    assert dump.returncode == 0 and '"aborted"' in dump.stdout, dump.stdout + dump.stderr  # closed, readable
    with open_campaign(out) as campaign:
        run = campaign.run(RUN_ID)
        assert (run.status, run.reason) == ("aborted", reason)
        z_m = np.asarray(run.channels["z_base_m"], dtype=float)
        fs = run.sample_rate_hz
    assert np.abs(z_m).max() > 1.5e-3  # it was at amplitude (2 mm)
    # no cut: a 2 mm sine at 10 Hz moves at most 2 pi f A / fs per sample, and the record ends at rest
    assert np.abs(np.diff(z_m)).max() <= 1.15 * 2 * np.pi * 10 * 2e-3 / fs
    assert np.abs(z_m[-round(fs / 10) :]).max() < 0.3e-3


@pytest.mark.validation
@pytest.mark.slow
@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_sigterm_mid_dwell_tapers_out_and_marks_the_run_aborted_with_the_signal(tmp_path):
    command, out = _command(tmp_path)
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        stdout, stderr = LineReader(proc.stdout), LineReader(proc.stderr)
        stdout.until(lambda line: line.startswith("progress:") and "at amplitude" in line, 60, "the dwell")
        proc.send_signal(signal.SIGTERM)
        told = stderr.next(60, "the handler's word")
        assert told.startswith("terminated (SIGTERM): stopping with a taper, the run marked aborted"), told
        rest = stdout.rest(DEADLINE_S)
        assert proc.wait(timeout=DEADLINE_S) == ExitCode.STOPPED
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert f"long_dwell: aborted: aborted: terminated by SIGTERM; file {out}" in rest
    _assert_tapered_and_aborted(out, "aborted: terminated by SIGTERM")


@pytest.mark.validation
@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_the_terminal_closing_mid_dwell_tapers_out_and_marks_the_run_aborted(tmp_path):
    command, out = _command(tmp_path)
    master, slave = pty.openpty()
    proc = subprocess.Popen(  # setsid: a session of its own whose controlling terminal is the pty
        ["setsid", "--ctty", "--wait", *command],
        stdin=slave,
        stdout=slave,
        stderr=slave,
        cwd=ROOT,
        env={**os.environ, "COLUMNS": "300"},  # the status line whole: it is cut at the width
    )
    os.close(slave)
    seen = b""
    try:
        while b"at amplitude" not in seen:
            try:
                chunk = os.read(master, 65536)
            except OSError as exc:  # EIO: the command closed the terminal (it ended)
                raise AssertionError(f"{exc}; exit code {proc.wait(5)}; read {seen[-2000:]!r}") from exc
            assert chunk, seen
            seen += chunk
        os.close(master)  # the terminal goes away: the kernel hangs up its session
        master = -1
        assert proc.wait(timeout=DEADLINE_S) == ExitCode.STOPPED
    finally:
        if master >= 0:
            os.close(master)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    _assert_tapered_and_aborted(out, "aborted: the terminal hung up (SIGHUP)")
