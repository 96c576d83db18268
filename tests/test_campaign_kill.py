"""``kill -9`` of a running ``wfsbench run`` mid-point, then ``wfsbench run --resume``.

The bench is simulated in real time (``paced = true``) so that the kill lands inside a point: the
test follows the run log the command prints per point and kills it 2 s into the second point (of
3.5 s). The file must open (h5py, h5dump), hold what the store's durability rule promises
(docs/hdf5.md: whole chunks of one second, written at least once a chunk is waiting, so less than
one second of samples only in memory), read ``incomplete``, and resume to a complete campaign with
every point done exactly once.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.app.pace import DoneBefore
from bench.app.plan import plan_campaign
from bench.app.resume import done_in_file
from bench.cli.exit_codes import ExitCode
from bench.engine.amplitude import amplitude_mm
from bench.numerics.sine_fit import fit_latest_cycles
from bench.store import open_campaign
from tests.commands import wfsbench
from tests.sequence_texts import sequence_text
from tests.test_campaign_cli import H5DUMP, ROOT
from tests.test_store_h5dump import parse_h5dump

RATE_HZ = 1000.0  # the WFS frame rate of the configuration: a store chunk is one second of it
RUN_ID = "killed-s002-dwell_grid"
SEQUENCE = sequence_text(
    "killed",
    """\
[[steps]]
type = "dwell_grid"
freqs_hz = [10, 20]
amplitudes_mm = [1]
settle_cycles = 2
settle_min_s = 0.1
measure_cycles = 2
measure_min_s = 3.0
taper_in_s = 0.2
taper_out_s = 0.2
""",
)
#: How far into point 1 the kill comes (wall clock, the bench being paced): beyond the one second
#: after which point 0's row must be durable, well before point 1's end (3.5 s).
KILL_AFTER_S = 2.0
#: Allowance (s) for the paced bench and the link's pipeline lagging the wall clock on a loaded machine.
SCHEDULING_S = 0.5
DEADLINE_S = 60.0  # wall clock, a timeout only
LAB_END_S = 20.0  # wall clock for the simulated lab's process to end after its bench, a timeout only


def _kill_mid_point(sequence: Path, out: Path, config: Path) -> tuple[list[str], float, int]:
    """Start the run, kill it ``KILL_AFTER_S`` after point 0 is logged done; return the log lines,
    the wall time from that line to the kill, and the killed process's id."""
    command = [
        sys.executable,
        "-m",
        "bench.cli",
        "run",
        str(sequence),
        "--out",
        str(out),
        "--bench",
        str(config),
    ]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, cwd=ROOT, env=env)
    lines: list[str] = []
    deadline = time.monotonic() + DEADLINE_S
    try:
        for line in proc.stdout:
            lines.append(line.rstrip("\n"))
            if line.startswith("  point 0 at 10 Hz: done"):
                break
            assert time.monotonic() < deadline, f"point 0 was not logged done: {lines}"
        else:
            pytest.fail(f"the run ended before point 0 was done (exit {proc.wait()}): {lines}")
        logged_s = time.monotonic()
        with pytest.raises(subprocess.TimeoutExpired):  # still running: point 1 is under way
            proc.wait(timeout=KILL_AFTER_S)
        proc.send_signal(signal.SIGKILL)
        killed_s = time.monotonic()
        lines += [line.rstrip("\n") for line in proc.stdout]
    finally:
        proc.kill()
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    return lines, killed_s - logged_s, proc.pid


def _links_of_gone_processes(before: set[Path]) -> list[Path]:
    """The pty link directories made since ``before`` whose process is gone (wfs-pty-<pid>-*)."""
    made = set(Path(tempfile.gettempdir()).glob("wfs-pty-*")) - before
    return [d for d in made if not Path(f"/proc/{d.name.split('-')[2]}").exists()]


@pytest.mark.validation
@pytest.mark.slow
@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_killed_run_leaves_a_readable_incomplete_file_that_resume_completes(tmp_path):
    sequence, config, out = tmp_path / "killed.toml", tmp_path / "paced.toml", tmp_path / "campaign.h5"
    sequence.write_text(SEQUENCE)
    # flow control: the test machine's own stalls (tenths of a second with three test workers on two
    # cores) would overrun a real tty's buffer and lose frames this test is not about
    config.write_text('kind = "shaker"\n[simulation]\npaced = true\nflow_control = true\n')
    links_before = set(Path(tempfile.gettempdir()).glob("wfs-pty-*"))
    lines, elapsed_s, _ = _kill_mid_point(sequence, out, config)
    # the simulated lab runs in a process of its own (paced): it sees its bench gone (its input
    # closes), stops its devices and removes its pty link
    deadline = time.monotonic() + LAB_END_S
    while (left := _links_of_gone_processes(links_before)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not left, f"the simulated lab's process left {left} after its bench was killed"
    assert not any(line.startswith("  point 1 at") for line in lines), lines  # killed inside point 1

    with h5py.File(out, "r") as f:  # a plain open, no h5clear
        assert f"/runs/{RUN_ID}/channels/z_base_m" in f
    dump = subprocess.run(
        [H5DUMP, "-H", "-p", str(out)], capture_output=True, text=True, timeout=60, check=True
    )
    assert f"/runs/{RUN_ID}/points" in parse_h5dump(dump.stdout)
    with open_campaign(out) as campaign:
        (run,) = campaign.runs
        assert run.run_id == RUN_ID and run.status == "incomplete" and run.finished == ""
        n = run.n_samples
        assert n % RATE_HZ == 0  # durable samples are whole one-second chunks
        done = [p for p in run.points if p.status == "done"]
        assert [p.index for p in done] == [0]  # logged done more than a second before the kill
        end_0 = done[0].end_sample
        # samples reach the file within a second of their arrival: those of point 1 up to a second
        # (and the allowance) before the kill are there
        assert n - end_0 >= (elapsed_s - 1.0 - SCHEDULING_S) * RATE_HZ, (n, end_0, elapsed_s)
        sample = run.channels["sample"]  # the WFS's own counter: nothing lost or garbled inside
        np.testing.assert_array_equal(sample, np.arange(sample[0], sample[0] + n))
        assert np.all(np.isfinite(run.channels["z_base_m"]))

    plan = plan_campaign(sequence, config)
    point_0 = plan.sequence.steps[2].dwells()[0]
    assert done_in_file(plan, out) == DoneBefore(points=1, estimated_s=point_0.duration_s)  # resume skips it

    resumed = wfsbench("run", str(sequence), "--out", str(out), "--bench", str(config), "--resume")
    assert resumed.returncode == ExitCode.INCOMPLETE, resumed.stderr
    assert "point 0" not in resumed.stdout and "point 1 at 20 Hz: done" in resumed.stdout
    assert "progress: 1/2 points" in resumed.stdout  # point 0, done before the kill, counts as done
    subprocess.run([H5DUMP, "-H", str(out)], capture_output=True, timeout=60, check=True)
    with open_campaign(out) as campaign:
        (run,) = campaign.runs
        assert run.status == "complete"
        assert sorted(p.index for p in run.points if p.status == "done") == [0, 1]  # each once
        assert run.n_samples > n
        assert [e.kind for e in run.events].count("resumed") == 1
        records = run.dwell_records()
        assert [r.freq_hz for r in records] == [10.0, 20.0]
        for record in records:  # each done point's slice holds its own dwell, recorded after the resume too
            start, stop = (round(t * record.sample_rate_hz) for t in record.hold_s)
            z = record.channels["z_base_m"][start:stop]
            fit = fit_latest_cycles(z, np.arange(z.size), record.sample_rate_hz, record.freq_hz)
            assert amplitude_mm(fit) == pytest.approx(1.0, rel=0.05)
