"""``wfsbench run`` for the lab: the answers file (checked whole before anything moves, applied to
the simulated world), Ctrl-C (a tapered abort, a second one an e-stop; the file kept and marked),
and the progress display (plain lines in a pipe, a live display of one line on a terminal)."""

from __future__ import annotations

import fcntl
import io
import math
import os
import pty
import re
import select
import shutil
import signal
import struct
import subprocess
import sys
import termios
from pathlib import Path

import numpy as np
import pytest

from bench.app.answers import AnswersError, FileAnswers, load_answers
from bench.app.interrupts import tell
from bench.app.pace import DoneBefore
from bench.app.progress import Progress
from bench.app.terminal import TerminalOperator
from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.config import load_bench_config
from bench.engine import events as ev
from bench.store import open_campaign
from sequences import Prompt, Sequence, load_sequence
from simulators.bench_sim import SimulatedBench
from simulators.world import SimulatedOperator, SimulatedWorld
from tests.commands import wfsbench
from tests.terminal_screen import Screen
from tests.test_campaign_cli import SMOKE, _bench_toml, lab_devices  # noqa: F401 - a fixture
from tests.waiting import LineReader

ROOT = Path(__file__).resolve().parents[1]
H5DUMP = shutil.which("h5dump")
SMOKE_ANSWERS = "remove_wheel = true\nfit_wheel = true\npressure = 2.4\n"


#: Point 0 of a grid at 10 Hz and 2 mm, done at its first attempt (a progress display's input).
POINT_0_DONE = ev.PointDone(
    0,
    10.0,
    2.0,
    0,
    10,
    200,
    250,
    commanded_amplitude_mm=2.0,
    achieved_amplitude_mm=2.0,
    run_id="seq-s002-dwell_grid",
)


def smoke_sequence():
    return load_sequence(SMOKE, load_bench_config(None).limits)


# -- the answers file -------------------------------------------------------------------------------


def test_an_answers_file_gives_every_prompt_its_checked_answer(tmp_path):
    path = tmp_path / "answers.toml"
    path.write_text('fit_wheel = "Yes"\nremove_wheel = true\npressure = 3\n')
    assert load_answers(path, smoke_sequence()) == {"remove_wheel": True, "fit_wheel": True, "pressure": 3.0}


def test_a_choice_is_a_word_whatever_its_case_in_a_file_and_at_the_terminal(tmp_path):
    """As yes and no are: "Medium" answers a choice of soft / medium / firm, recorded as "medium"."""
    damper = Prompt("damper", "Damper setting?", answer="choice", choices=("soft", "medium", "firm"))
    sequence = Sequence("d", "", (damper,), "<test>")
    path = tmp_path / "answers.toml"
    path.write_text('damper = "Medium"\n')
    assert load_answers(path, sequence) == {"damper": "medium"}
    typed = iter(["Hard", " FIRM "])
    said = []
    assert TerminalOperator(read=lambda q: next(typed), write=said.append).answer(damper) == "firm"
    assert said == ["  damper: 'Hard' is not one of ['soft', 'medium', 'firm']; try again"]
    path.write_text("damper = 2\n")
    with pytest.raises(AnswersError, match=r"damper: 2 is an integer, not one of the choices \(a string\)"):
        load_answers(path, sequence)


BAD_ANSWERS = {
    "missing answer": (
        "remove_wheel = true\nfit_wheel = true\n",
        "answers.toml: pressure: no answer for the prompt 'Set the tyre pressure to 2.5 bar and enter the"
        " pressure read on the gauge'; allowed: [0.5..4.5 bar]",
    ),
    "out of range": (
        "remove_wheel = true\nfit_wheel = true\npressure = 6.5\n",
        "answers.toml: pressure: 6.5 is not a number within 0.5..4.5 bar; allowed: [0.5..4.5 bar]",
    ),
    "text for a number": (
        'remove_wheel = true\nfit_wheel = true\npressure = "high"\n',
        'answers.toml: pressure: "high" is a string, not a number (write the number without quotes);'
        " allowed: [0.5..4.5 bar]",
    ),
    "a number in quotes": (
        'remove_wheel = true\nfit_wheel = true\npressure = "2.4"\n',
        'answers.toml: pressure: "2.4" is a string, not a number (write the number without quotes);'
        " allowed: [0.5..4.5 bar]",
    ),
    "a boolean for a number": (
        "remove_wheel = true\nfit_wheel = true\npressure = true\n",
        "answers.toml: pressure: true is a boolean, not a number; allowed: [0.5..4.5 bar]",
    ),
    "typed text for a confirmation": (
        'remove_wheel = true\nfit_wheel = "y"\npressure = 2.4\n',
        'answers.toml: fit_wheel: "y" is not a confirmation: true or false (or "yes" / "no");'
        " allowed: [yes / no]",
    ),
    "a number for a confirmation": (
        "remove_wheel = 1\nfit_wheel = true\npressure = 2.4\n",
        'answers.toml: remove_wheel: 1 is not a confirmation: true or false (or "yes" / "no");'
        " allowed: [yes / no]",
    ),
    "not a confirmation": (
        'remove_wheel = "maybe"\nfit_wheel = true\npressure = 2.5\n',
        'answers.toml: remove_wheel: "maybe" is not a confirmation: true or false (or "yes" / "no");'
        " allowed: [yes / no]",
    ),
    "unknown prompt id": (
        SMOKE_ANSWERS + "presure = 2.5\n",
        "answers.toml: presure: no prompt of sequence 'smoke' has this id"
        " (its prompts: remove_wheel, fit_wheel, pressure)",
    ),
    "not TOML": (SMOKE_ANSWERS + "pressure 2\n", "answers.toml: line 4: not valid TOML: "),
    "duplicate key": (
        SMOKE_ANSWERS + "pressure = 2.5\n",
        "answers.toml: pressure: line 4: duplicate key: it is already defined above in the same table",
    ),
    "no to a confirmation": (
        'remove_wheel = true\nfit_wheel = "no"\npressure = 2.5\n',
        "answers.toml: fit_wheel: answered no to the confirmation 'Fit the wheel with the sensor and clamp"
        " the wheel centre': the sequence would abort there; an unattended run needs yes",
    ),
}


@pytest.mark.parametrize("case", BAD_ANSWERS.values(), ids=BAD_ANSWERS.keys())
def test_a_bad_answers_file_is_refused_before_anything_moves(tmp_path, lab_devices, capsys, case):  # noqa: F811
    """Against a served controller: exit code 3, the file, the prompt id and the allowed range named,
    no write reached the controller and no campaign file was created."""
    text, named = case
    server, pty = lab_devices
    answers, config, out = tmp_path / "answers.toml", tmp_path / "bench.toml", tmp_path / "c.h5"
    answers.write_text(text)
    config.write_text(_bench_toml(server, pty))
    code = main(["run", str(SMOKE), "--out", str(out), "--bench", str(config), "--answers", str(answers)])
    assert code == ExitCode.INVALID
    assert f"error: {tmp_path}/{named}" in capsys.readouterr().err
    assert server.writes_received == 0
    assert not out.exists()


def test_every_problem_of_an_answers_file_is_reported_in_the_order_of_the_file(tmp_path):
    """The file's keys in its order (not sorted), then the prompts it leaves unanswered."""
    path = tmp_path / "answers.toml"
    path.write_text('presure = 2.5\nremove_wheel = "maybe"\nfit_wheel = false\nfit = true\n')
    with pytest.raises(AnswersError) as refused:
        load_answers(path, smoke_sequence())
    prompts = "(its prompts: remove_wheel, fit_wheel, pressure)"
    assert str(refused.value).splitlines() == [
        f"{path}: presure: no prompt of sequence 'smoke' has this id {prompts}",
        "  and 4 more:",
        f'  {path}: remove_wheel: "maybe" is not a confirmation: true or false (or "yes" / "no");'
        " allowed: [yes / no]",
        f"  {path}: fit_wheel: answered no to the confirmation 'Fit the wheel with the sensor and clamp"
        " the wheel centre': the sequence would abort there; an unattended run needs yes",
        f"  {path}: fit: no prompt of sequence 'smoke' has this id {prompts}",
        f"  {path}: pressure: no answer for the prompt 'Set the tyre pressure to 2.5 bar and enter the"
        " pressure read on the gauge'; allowed: [0.5..4.5 bar]",
    ]
    assert len(refused.value.problems) == 5


def test_a_missing_answers_file_is_refused_by_the_command(tmp_path):
    run = wfsbench("run", str(SMOKE), "--out", str(tmp_path / "c.h5"), "--answers", str(tmp_path / "no.toml"))
    assert run.returncode == ExitCode.INVALID
    assert f"error: {tmp_path}/no.toml: cannot read the answers file" in run.stderr
    assert not (tmp_path / "c.h5").exists()


def test_file_answers_are_applied_to_the_simulated_world():
    world = SimulatedWorld(SimulatedBench.paper_shaker(seed=1), kind="shaker", pressure_bar=2.5)
    operator = FileAnswers({"remove_wheel": True, "pressure": 1.8}, SimulatedOperator(world))
    prompts = {step.id: step for step in smoke_sequence().steps if getattr(step, "kind", "") == "prompt"}
    assert operator.answer(prompts["pressure"]) == 1.8
    assert world.pressure_bar == 1.8
    assert operator.answer(prompts["remove_wheel"]) is True
    assert not world.specimen_mounted


def test_an_unattended_run_records_the_file_answers(tmp_path):
    """The smoke sequence with its prompts answered from the file, through the command: the
    pressure answered (2.4 bar, not the prompt's 2.5 target) is the grid's recorded condition."""
    answers, out = tmp_path / "answers.toml", tmp_path / "smoke.h5"
    answers.write_text(SMOKE_ANSWERS)
    run = wfsbench("run", str(SMOKE), "--out", str(out), "--answers", str(answers))
    assert run.returncode == ExitCode.OK, run.stderr
    assert "enter the pressure read on the gauge -> 2.4 bar" in run.stdout
    with open_campaign(out) as campaign:
        grid = campaign.run("smoke-s009-dwell_grid")
        assert grid.conditions["tyre_pressure_bar"] == 2.4
        assert grid.results("shaker")["tyre_pressure_bar"] == 2.4
        answered = {e.fields["prompt_id"]: e.fields["answer"] for e in campaign.events if e.kind == "prompt"}
    assert answered == {"remove_wheel": True, "fit_wheel": True, "pressure": 2.4}


# -- Ctrl-C -----------------------------------------------------------------------------------------

LONG_DWELL = """\
[sequence]
name = "long_dwell"

[[steps]]
type = "hydraulics"
level = "low"

[[steps]]
type = "hydraulics"
level = "high"

[[steps]]
type = "sine_dwell"
freq_hz = {freq_hz}
amplitude_mm = {amplitude_mm}
measure_min_s = 60
taper_out_s = {taper_out_s}
"""
RUN_ID = "long_dwell-s002-sine_dwell"


def long_dwell_command(
    tmp_path: Path, taper_out_s: float, *, flow_control: bool = True
) -> tuple[list[str], Path]:
    """The command of a paced ``wfsbench run`` of a 60 s dwell of 2 mm at 10 Hz, and its campaign
    file. With ``flow_control`` the simulated WFS waits for a reader the test machine holds up (its
    own stalls, tenths of a second beside other test workers, would overrun a real tty's buffer and
    lose frames a test of signals is not about); without it a held reader loses frames as a real
    port's would."""
    sequence, out = tmp_path / "long.toml", tmp_path / "long.h5"
    sequence.write_text(LONG_DWELL.format(freq_hz=10, amplitude_mm=2, taper_out_s=taper_out_s))
    script = Path(sys.executable).with_name("wfsbench")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bench.cli"]
    command += ["run", str(sequence), "--out", str(out)]
    if not flow_control:
        return [*command, "--realtime"], out
    config = tmp_path / "paced.toml"
    config.write_text('kind = "shaker"\n[simulation]\npaced = true\nflow_control = true\n')
    return [*command, "--bench", str(config)], out


def long_dwell_run(
    tmp_path: Path, taper_out_s: float, *, stderr: int = subprocess.PIPE, flow_control: bool = True
) -> tuple[subprocess.Popen, Path]:
    """:func:`long_dwell_command` started (text pipes: its standard output, and its standard error
    unless ``stderr`` says where), and its campaign file."""
    command, out = long_dwell_command(tmp_path, taper_out_s, flow_control=flow_control)
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        cwd=ROOT,
    )
    return proc, out


def _interrupted_run(tmp_path: Path, taper_out_s: float, signals: int) -> tuple[int, str, Path]:
    """``wfsbench run --realtime`` of a 60 s dwell, sent ``signals`` SIGINTs once the progress shows
    the dwell at full amplitude (the next one once the command has told the previous was taken):
    its exit code, standard error and campaign file."""
    proc, out = long_dwell_run(tmp_path, taper_out_s)
    try:
        stdout, stderr = LineReader(proc.stdout), LineReader(proc.stderr)
        stdout.until(lambda line: line.startswith("progress:") and "at amplitude" in line, 60, "the dwell")
        told = []
        for _ in range(signals):
            proc.send_signal(signal.SIGINT)
            told.append(stderr.next(60, "the handler's word"))  # the interrupt was taken
            assert told[-1].startswith("interrupted"), told
        stdout.rest(60)
        code = proc.wait(timeout=60)
        return code, "".join(told) + stderr.rest(60), out
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _h5dump_status(path: Path) -> str:
    dump = subprocess.run(
        [H5DUMP, "-a", f"/runs/{RUN_ID}/status", str(path)], capture_output=True, text=True, check=True
    )
    return dump.stdout


def _cycle_peaks_mm(z_m: np.ndarray, samples_per_cycle: int) -> np.ndarray:
    n = len(z_m) // samples_per_cycle
    return np.abs(z_m[: n * samples_per_cycle].reshape(n, samples_per_cycle)).max(axis=1) * 1e3


@pytest.mark.slow
@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_ctrl_c_mid_dwell_tapers_out_keeps_the_file_and_marks_the_run_aborted(tmp_path):
    code, stderr, out = _interrupted_run(tmp_path, taper_out_s=0.5, signals=1)
    assert code == ExitCode.STOPPED, stderr
    assert '"aborted"' in _h5dump_status(out)
    with open_campaign(out) as campaign:
        run = campaign.run(RUN_ID)
        assert run.status == "aborted"
        z_m = np.asarray(run.channels["z_base_m"], dtype=float)
        fs = run.sample_rate_hz
    # no jump: a 2 mm sine at 10 Hz moves at most 2 pi f A / fs per sample; a cut to rest would
    # move up to 2 mm in one
    assert np.abs(np.diff(z_m)).max() <= 1.15 * 2 * math.pi * 10 * 2e-3 / fs
    # the decay: after the last full-amplitude cycle the peaks fall cycle by cycle through the taper
    # (0.5 s: five cycles at 10 Hz; a cut would leave none between 90 % and 10 %) to rest
    peaks = _cycle_peaks_mm(z_m, round(fs / 10))
    last_full = int(np.flatnonzero(peaks >= 0.9 * 2)[-1])
    decay = peaks[last_full:]
    assert np.all(np.diff(decay[decay > 0.2]) < 0), peaks  # down to the noise of a bench at rest
    assert np.count_nonzero((decay > 0.2) & (decay < 1.8)) >= 3, peaks
    # the record runs to the taper's end or past it: its last cycle is the taper's last tenth
    # (2 mm times a raised cosine's 0.095 at most there) or rest
    assert np.abs(z_m[-round(fs / 10) :]).max() * 1e3 < 0.3, peaks

    # the interrupted dwell is repeated by --resume (unpaced: seconds), and the run completes
    resumed = wfsbench("run", str(tmp_path / "long.toml"), "--out", str(out), "--resume")
    assert resumed.returncode == ExitCode.INCOMPLETE, resumed.stdout + resumed.stderr
    with open_campaign(out) as campaign:
        run = campaign.run(RUN_ID)
        assert run.status == "complete"
        assert [p.index for p in run.points if p.status == "done"] == [0]
        (resumed_event,) = [e for e in run.events if e.kind == "resumed"]
        assert resumed_event.fields["ended"] == "aborted"


@pytest.mark.validation
@pytest.mark.slow
@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_a_second_ctrl_c_during_the_taper_e_stops(tmp_path):
    """A 5 s taper out: the second SIGINT, sent once the first was taken, lands inside it."""
    code, stderr, out = _interrupted_run(tmp_path, taper_out_s=5.0, signals=2)
    assert code == ExitCode.STOPPED, stderr
    assert "interrupted again: e-stop" in stderr
    assert '"e-stopped"' in _h5dump_status(out)


# -- progress ---------------------------------------------------------------------------------------


class FakeClock:
    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


def _feed(progress: Progress, clock: FakeClock) -> None:
    """A 4-point sequence estimated at 10 s; point 1 started after 2.5 s recorded in 1 s wall time."""
    progress(ev.SequenceStarted("seq", "", "", 4, 10.0))
    progress(ev.RunStarted("seq-s002-dwell_grid", "dwell_grid", {}, {"tyre_pressure_bar": 2.5}, (), 100.0))
    progress(ev.PointStarted("seq-s002-dwell_grid", 0, 1, 10.0, 2.0, {"tyre_pressure_bar": 2.5}))
    clock.now_s += 1.0
    progress(ev.SamplesRecorded("seq-s002-dwell_grid", 0, {"status": np.zeros(250, np.uint16)}))
    progress(POINT_0_DONE)
    progress.line("  point 0 at 10 Hz: done")
    progress(ev.PointStarted("seq-s002-dwell_grid", 1, 1, 30.0, 1.5, {"tyre_pressure_bar": 2.5}))


def test_progress_in_a_pipe_is_plain_lines_with_the_eta_scaled_by_the_observed_rate():
    clock, out = FakeClock(), io.StringIO()
    progress = Progress(out, live=False, clock=clock)
    _feed(progress, clock)
    lines = out.getvalue().splitlines()
    assert lines == [
        "progress: 0/4 points | elapsed 0:00, ETA --:-- | seq-s002-dwell_grid point 0: 10 Hz, 2 mm,"
        " 2.5 bar, tapering in",
        "  point 0 at 10 Hz: done",
        # 7.5 s of the estimate left at 1 wall second per 2.5 recorded seconds: 3 s
        "progress: 1/4 points | elapsed 0:01, ETA 0:03 | seq-s002-dwell_grid point 1: 30 Hz, 1.5 mm,"
        " 2.5 bar, tapering in",
    ]
    assert math.isclose(progress.eta_s, 3.0)


def test_a_resumed_file_s_points_count_as_done_and_their_duration_is_not_ahead():
    clock, out = FakeClock(), io.StringIO()
    progress = Progress(out, live=False, clock=clock, done_before=DoneBefore(points=2, estimated_s=5.0))
    _feed(progress, clock)
    # 10 s estimated, 5 s of it done before, 2.5 s recorded now at 1 wall second: 2.5 s ahead, 1 s
    assert out.getvalue().splitlines()[-1].startswith("progress: 3/4 points | elapsed 0:01, ETA 0:01")
    assert math.isclose(progress.eta_s, 1.0)


def test_the_eta_goes_by_the_points_once_the_estimated_duration_is_spent():
    """An adaptive grid's estimate holds each dwell at its shortest: recorded time overtakes it."""
    clock, out = FakeClock(), io.StringIO()
    progress = Progress(out, live=False, clock=clock)
    progress(ev.SequenceStarted("seq", "", "", 4, 1.0))
    progress(ev.RunStarted("seq-s002-dwell_grid", "dwell_grid", {}, {}, (), 100.0))
    clock.now_s += 1.0
    progress(ev.SamplesRecorded("seq-s002-dwell_grid", 0, {"status": np.zeros(250, np.uint16)}))
    progress(POINT_0_DONE)
    assert math.isclose(progress.eta_s, 3.0)  # 3 points to go at 1 wall second per point, not 0


def test_points_an_adaptive_grid_adds_count_in_the_total():
    clock, out = FakeClock(), io.StringIO()
    progress = Progress(out, live=False, clock=clock)
    _feed(progress, clock)
    progress(ev.GridRefined("seq-s002-dwell_grid", 2.0, ((35.0, "model peak"), (32.5, "steep"))))
    progress(ev.PointStarted("seq-s002-dwell_grid", 4, 1, 35.0, 2.0, {"tyre_pressure_bar": 2.5}))
    assert out.getvalue().splitlines()[-1].startswith("progress: 1/6 points")


def test_progress_on_a_terminal_is_one_live_line_below_the_log_and_gone_at_the_end(monkeypatch):
    """The log line whole above the status, the status with its figures on one line below it,
    redrawn in place; once the sequence ends only the log is left, and the cursor is shown again."""
    monkeypatch.setenv("COLUMNS", "300")  # the status whole: it is cut at the terminal's width
    clock, out = FakeClock(), io.StringIO()
    progress = Progress(out, live=True, clock=clock)
    _feed(progress, clock)
    screen = Screen().feed(out.getvalue())
    assert screen.shown == ["  point 0 at 10 Hz: done", screen.current]  # the display: the line below
    assert screen.current.endswith(
        " 1/4 points | elapsed 0:01, ETA 0:03 | seq-s002-dwell_grid point 1: 30 Hz, 1.5 mm, 2.5 bar,"
        " tapering in"
    )
    assert "progress:" not in out.getvalue()
    progress(ev.SequenceFinished("complete", ""))
    screen = Screen().feed(out.getvalue())
    assert screen.shown == ["  point 0 at 10 Hz: done"]
    assert (screen.row, screen.column, screen.cursor_shown) == (1, 0, True)  # where the next line goes


def test_on_a_narrow_terminal_the_status_is_cut_at_its_width_and_log_lines_stay_whole(monkeypatch):
    monkeypatch.setenv("COLUMNS", "60")
    clock, out = FakeClock(), io.StringIO()
    progress = Progress(out, live=True, clock=clock)
    _feed(progress, clock)
    long_line = "  point 1 at 30 Hz: done, commanded 1.500 mm, achieved 1.498 mm; settled, u 0.12 % / 0.1 deg"
    progress.line(long_line)
    progress(ev.PointStarted("seq-s002-dwell_grid", 2, 1, 40.0, 1.5, {"tyre_pressure_bar": 2.5}))
    screen = Screen().feed(out.getvalue())
    assert screen.shown == ["  point 0 at 10 Hz: done", long_line, screen.current]  # neither wrapped
    assert len(screen.current) == 60 and screen.current.endswith("…")
    assert " 1/4 points | elapsed 0:01, ETA 0:03 | seq-s002" in screen.current


def test_a_dumb_terminal_takes_the_plain_lines(monkeypatch):
    """A terminal that cannot erase a line (an editor's shell buffer) gets what a pipe gets."""
    master, slave = os.openpty()
    try:
        with os.fdopen(os.dup(slave), "w") as terminal:
            monkeypatch.setenv("TERM", "xterm-256color")
            assert Progress(terminal).live
            monkeypatch.setenv("TERM", "dumb")
            assert not Progress(terminal).live
    finally:
        os.close(master)
        os.close(slave)


def test_the_command_in_a_pipe_writes_no_control_codes(tmp_path):
    answers = tmp_path / "answers.toml"
    answers.write_text(SMOKE_ANSWERS)
    run = wfsbench("run", str(SMOKE), "--out", str(tmp_path / "c.h5"), "--answers", str(answers))
    assert run.returncode == ExitCode.OK, run.stderr
    assert "\x1b" not in run.stdout and "\r" not in run.stdout
    progress = [line for line in run.stdout.splitlines() if line.startswith("progress: ")]
    assert (
        progress[0]
        == "progress: 0/8 points | elapsed 0:00, ETA --:-- | waiting for the operator: prompt remove_wheel"
    )
    assert progress[1].startswith(
        "progress: 0/8 points | elapsed 0:00, ETA --:-- | smoke-s003-free_run point 0"
    )
    sweep = "smoke-s010-sweep: sweep 1-30 Hz, 1 mm, 2.4 bar"
    assert any(line.startswith("progress: 7/8 points | ") and line.endswith(sweep) for line in progress)


def terminal_of(columns: int) -> tuple[int, int]:
    """A pseudo-terminal ``columns`` wide (master, slave), as a terminal window is."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, columns, 0, 0))
    return master, slave


def terminal_env() -> dict[str, str]:
    """The environment of a command on a terminal: a terminal that redraws, its width its own."""
    env = {key: value for key, value in os.environ.items() if key not in ("COLUMNS", "LINES")}
    return {**env, "TERM": "xterm-256color"}


@pytest.mark.validation
def test_the_command_on_a_terminal_shows_a_live_status_that_leaves_only_the_log(tmp_path):
    """Standard output a pseudo-terminal 200 columns wide: the status is drawn with its figures (the
    sweep under way, 7 of 8 points done), never wider than the terminal; at the end the screen holds
    the run log whole, the statuses the prompts left (where the bench waited) and nothing else of the
    display, and the cursor is shown."""
    answers, out = tmp_path / "answers.toml", tmp_path / "c.h5"
    answers.write_text(SMOKE_ANSWERS)
    script = Path(sys.executable).with_name("wfsbench")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bench.cli"]
    master, slave = terminal_of(200)
    proc = subprocess.Popen(
        [*command, "run", str(SMOKE), "--out", str(out), "--answers", str(answers)],
        stdin=subprocess.DEVNULL,
        stdout=slave,
        stderr=subprocess.PIPE,
        cwd=ROOT,
        env=terminal_env(),
    )
    os.close(slave)
    chunks = []
    try:
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the command closed the terminal's last writer
                break
            if not chunk:
                break
            chunks.append(chunk)
        assert proc.wait(timeout=120) == ExitCode.OK, proc.stderr.read()
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    text = b"".join(chunks).decode()
    assert "progress:" not in text
    screen = Screen().feed(text)
    sweep = r".* 7/8 points \| elapsed \d+:\d\d, ETA \S+ \| smoke-s010-sweep: sweep 1-30 Hz, 1 mm, 2\.4 bar"
    assert any(re.fullmatch(sweep, drawn) for drawn in screen.erased), screen.erased
    statuses = [line for line in screen.shown if " points | elapsed " in line]
    assert max(map(len, screen.erased + statuses)) <= 200
    assert [status.rpartition(" | ")[2] for status in statuses] == [
        f"waiting for the operator: prompt {prompt}" for prompt in ("remove_wheel", "fit_wheel", "pressure")
    ]
    assert "  point 0 at 10 Hz: done" in [line[:24] for line in screen.shown]
    assert screen.shown[-1] == f"smoke: complete; file {out}"
    assert screen.cursor_shown


PROMPT_FIRST = """\
[sequence]
name = "asks"

[[steps]]
type = "hydraulics"
level = "low"

[[steps]]
type = "prompt"
id = "ready"
text = "Is the bench clear"
answer = "confirm"

[[steps]]
type = "hydraulics"
level = "off"
"""


@pytest.mark.validation
@pytest.mark.slow
def test_ctrl_c_while_the_terminal_waits_for_an_answer_aborts_the_sequence(tmp_path, lab_devices):  # noqa: F811
    """Real devices (served on 127.0.0.1 and a pty) and no answers file: the prompt is read from
    standard input, which stays open; Ctrl-C there is no answer, and the sequence ends aborted."""
    server, pty_path = lab_devices
    sequence, config = tmp_path / "asks.toml", tmp_path / "bench.toml"
    sequence.write_text(PROMPT_FIRST)
    config.write_text(_bench_toml(server, pty_path))
    script = Path(sys.executable).with_name("wfsbench")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bench.cli"]
    proc = subprocess.Popen(
        [*command, "run", str(sequence), "--out", str(tmp_path / "c.h5"), "--bench", str(config)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=ROOT,
    )
    try:
        shown = b""
        while b"Is the bench clear [yes / no]: " not in shown:  # input() writes its question unended
            chunk = proc.stdout.read1(4096)
            assert chunk, f"the command ended before asking: {shown!r} {proc.stderr.read()!r}"
            shown += chunk
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == ExitCode.STOPPED, err
    assert b"interrupted: stopping with a taper" in err
    assert b"sequence aborted: no valid answer to prompt 'ready'" in shown + out


def test_ctrl_c_before_the_devices_open_ends_the_command_without_a_traceback(tmp_path, monkeypatch, capsys):
    """An interrupt during the validation and the dry run (the first second or so of a large
    sequence): nothing moved, no file, exit code 1."""

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("bench.app.plan.plan_campaign", interrupted)
    out = tmp_path / "c.h5"
    assert main(["run", str(SMOKE), "--out", str(out)]) == ExitCode.STOPPED
    assert capsys.readouterr().err == "interrupted: nothing moved\n"
    assert not out.exists()


def test_the_interrupt_s_word_clears_the_progress_line_on_a_terminal_only(monkeypatch):
    master, slave = os.openpty()
    try:
        with os.fdopen(os.dup(slave), "w") as terminal:
            monkeypatch.setattr(sys, "stderr", terminal)
            tell("interrupted")
        assert os.read(master, 100) == b"\r\x1b[Kinterrupted\r\n"  # the pty's line discipline adds \r
    finally:
        os.close(master)
        os.close(slave)
    read_end, write_end = os.pipe()
    with os.fdopen(write_end, "w") as pipe:
        monkeypatch.setattr(sys, "stderr", pipe)
        tell("interrupted")
    with os.fdopen(read_end, "rb") as pipe:
        assert pipe.read() == b"interrupted\n"


def test_a_prompt_on_a_terminal_gets_a_line_of_its_own_and_the_status_says_the_bench_waits(monkeypatch):
    """At a prompt the status says the bench waits and is left as a line of its own, the cursor
    below it and shown; nothing is drawn until the answer (a log line is only the line); then the
    display comes back below."""
    monkeypatch.setenv("COLUMNS", "300")  # the status whole: it is cut at the terminal's width
    clock, out = FakeClock(), io.StringIO()
    progress = Progress(out, live=True, clock=clock)
    _feed(progress, clock)
    progress(ev.SamplesRecorded("seq-s002-dwell_grid", 250, {"status": np.full(10, 0xFFFF, np.uint16)}))
    progress(ev.PromptAsked("fit_wheel", "Fit the wheel"))
    screen = Screen().feed(out.getvalue())
    waiting = screen.shown[-1]
    assert waiting.endswith(
        " 1/4 points | elapsed 0:01, ETA 0:03 | waiting for the operator: prompt fit_wheel"
    )  # no longer "at amplitude": the point's phase is not the bench's
    assert (screen.current, screen.column, screen.cursor_shown) == ("", 0, True)  # the question's line
    asked = len(out.getvalue())
    clock.now_s += 5.0
    progress(ev.SamplesRecorded("seq-s002-dwell_grid", 260, {"status": np.zeros(100, np.uint16)}))
    progress.line("  a log line while the question waits")
    assert out.getvalue()[asked:] == "  a log line while the question waits\n"  # nothing drawn
    progress(ev.PromptAnswered("fit_wheel", "Fit the wheel", True, None))
    progress(ev.PointStarted("seq-s002-dwell_grid", 2, 1, 40.0, 1.5, {}))
    screen.feed(out.getvalue()[asked:])
    assert screen.shown[-3:-1] == [waiting, "  a log line while the question waits"]
    assert screen.current.endswith("| seq-s002-dwell_grid point 2: 40 Hz, 1.5 mm, 2.5 bar, tapering in")


ASKS_AFTER_A_DWELL = """\
[sequence]
name = "asks_later"

[[steps]]
type = "hydraulics"
level = "low"

[[steps]]
type = "hydraulics"
level = "high"

[[steps]]
type = "sine_dwell"
freq_hz = 10
amplitude_mm = 1
measure_min_s = 0.5

[[steps]]
type = "prompt"
id = "ready"
text = "Is the bench clear"
answer = "confirm"

[[steps]]
type = "hydraulics"
level = "off"
"""


@pytest.mark.validation
@pytest.mark.slow
def test_the_terminal_s_question_starts_its_own_line_below_the_status(tmp_path, lab_devices):  # noqa: F811
    """Real devices and the command on a pseudo-terminal (its standard input and output): the
    question comes on a line of its own, below a status that says the bench waits for the operator,
    the cursor shown; nothing is drawn over the question or the answer typed (the terminal's echo)."""
    server, pty_path = lab_devices
    sequence, config = tmp_path / "asks.toml", tmp_path / "bench.toml"
    sequence.write_text(ASKS_AFTER_A_DWELL)
    config.write_text(_bench_toml(server, pty_path))
    script = Path(sys.executable).with_name("wfsbench")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bench.cli"]
    master, slave = terminal_of(300)  # the status whole: it is cut at the terminal's width
    proc = subprocess.Popen(
        [*command, "run", str(sequence), "--out", str(tmp_path / "c.h5"), "--bench", str(config)],
        stdin=slave,  # all three the terminal: input() writes its question to standard error there
        stdout=slave,
        stderr=slave,
        cwd=ROOT,
        env=terminal_env(),
    )
    os.close(slave)
    shown = b""
    try:
        while b"Is the bench clear [yes / no]: " not in shown:
            ready, _, _ = select.select([master], [], [], 60.0)
            assert ready, f"no question within 60 s: {shown!r}"
            chunk = os.read(master, 65536)
            assert chunk, shown
            shown += chunk
        os.write(master, b"yes\n")
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the command ended, the terminal's last writer closed
                break
            if not chunk:
                break
            shown += chunk
        assert proc.wait(timeout=120) == ExitCode.INCOMPLETE, shown
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    question = "Is the bench clear [yes / no]: "
    screen = Screen().feed(shown.decode().split(question)[0])
    assert screen.shown[-1].endswith("| waiting for the operator: prompt ready")
    assert (screen.current, screen.column, screen.cursor_shown) == ("", 0, True)
    answered = Screen().feed(shown.decode()).shown
    at = answered.index(f"{question}yes")
    assert answered[at - 1] == screen.shown[-1]
