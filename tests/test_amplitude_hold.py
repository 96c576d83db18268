"""Amplitude held within the dwell: the controller's amplitude update (ramped, refused outside a
dwell's hold and beyond its limits), the client's checks, and the engine bringing the achieved
amplitude to its target during the hold on the simulated lab, with its fallback to repeats.

Physics: the simulated servo-hydraulic actuator overshoots with the wheel by +2.3 / +4.7 / +7.7 /
+11.6 % at 40 / 50 / 60 / 70 Hz (docs/physics.md); a dwell commanded at the target is therefore off
by more than the 2 % a repeat tolerates from about 45 Hz on. Held within the dwell the update
tolerance is 0.5 %; the achieved amplitude of the measured part is within 1 % (the update leaves
0.5 % plus the gain's small change with amplitude and the displacement noise, 2 um rms, 0.03 % of
the amplitude over a 0.1 s window). Where the valve's flow limit saturates (5 mm at 46-55 Hz,
1.5 m/s against the valve's 1.2 m/s) more command buys little amplitude: 2 % is the bound there.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.store import open_campaign
from drivers.errors import CommandRejectedError, LimitError, RegisterMapError
from drivers.register_map import (
    Command,
    ControllerState,
    ErrorCode,
    WaveformCode,
    default_map_path,
    load_register_map,
)
from drivers.setpoints import AmplitudeUpdate
from drivers.wfs_frame import Status
from sequences import DwellGrid, Hydraulics, Prompt, Sequence, Tare
from sequences.limits import BenchLimits
from simulators.controller_model import ControllerModel
from simulators.function_generator import AMPLITUDE_HOLD
from tests.campaign_lab import bench_config, grid_sequence, lab_campaign

RATE = 10_000.0
DWELL = {
    "waveform": WaveformCode.SINE_DWELL, "amplitude_mm": 2.0, "frequency_hz": 50.0, "dwell_s": 1.0,
    "taper_in_s": 0.2, "taper_out_s": 0.2, "mean_mm": 0.0, "watchdog_ms": 0,
}  # fmt: skip


def running_dwell() -> ControllerModel:
    model = ControllerModel(RATE)
    for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH):
        assert model.command(command) is None
    assert model.write_setpoints(DWELL) is None
    assert model.command(Command.START) is None
    return model


def advance(model: ControllerModel, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """The command (m) and its hold sync bit over the next ``seconds``."""
    command = model.command_block(round(seconds * RATE))
    return command, (model.generator.take_sync_flags() & AMPLITUDE_HOLD) != 0


def test_an_update_in_the_hold_ramps_with_the_hold_output_low_then_holds_the_dwell_again():
    model = running_dwell()
    advance(model, 0.5)  # taper in, 0.3 s of hold
    assert model.write_setpoints({"amplitude_update_mm": 1.5, "amplitude_ramp_s": 0.1}) is None
    command, hold = advance(model, 1.5)
    ramp = round(0.1 * RATE)
    held = round(1.0 * RATE)
    assert not hold[:ramp].any() and hold[ramp : ramp + held].all() and not hold[ramp + held :].any()
    period = round(RATE / 50)
    assert np.ptp(command[:period]) / 2 == pytest.approx(2e-3, rel=0.01)  # the ramp starts where it was
    assert np.ptp(command[ramp : ramp + period]) / 2 == pytest.approx(1.5e-3, rel=1e-3)
    late = command[ramp + held - period : ramp + held]
    assert np.ptp(late) / 2 == pytest.approx(1.5e-3, rel=1e-3)
    assert model.state is ControllerState.HYDRAULICS_HIGH  # the taper out followed the hold: at rest
    assert model.setpoints["amplitude_update_mm"] == 1.5  # reads back the amplitude taken


@pytest.mark.parametrize(
    ("when_s", "values", "reason"),
    [
        (0.1, {"amplitude_update_mm": 1.5}, ErrorCode.NOT_ALLOWED_IN_STATE),  # tapering in
        (1.3, {"amplitude_update_mm": 1.5}, ErrorCode.NOT_ALLOWED_IN_STATE),  # tapering out
        (0.5, {"amplitude_update_mm": 51.0}, ErrorCode.INVALID_SETPOINT),  # beyond the stroke
        (0.5, {"amplitude_update_mm": 1.5, "amplitude_ramp_s": 0.01}, ErrorCode.INVALID_SETPOINT),  # a step
        (0.5, {"amplitude_update_mm": 31.0, "displacement_limit_mm": 30.0}, ErrorCode.INVALID_SETPOINT),
    ],
)
def test_an_update_outside_the_hold_or_the_limits_is_refused_and_changes_nothing(when_s, values, reason):
    model = running_dwell()
    if "displacement_limit_mm" in values:
        assert model.write_setpoints({"displacement_limit_mm": values.pop("displacement_limit_mm")}) is None
    advance(model, when_s)
    before = dict(model.setpoints)
    assert model.write_setpoints(values) == reason
    advance(model, 0.05)
    assert model.setpoints == before
    assert model.generator.amplitude_m == pytest.approx(2e-3)


def test_a_controller_at_rest_refuses_an_update():
    model = ControllerModel(RATE)
    assert model.write_setpoints({"amplitude_update_mm": 1.0}) == ErrorCode.NOT_ALLOWED_IN_STATE


def test_a_map_naming_one_of_the_update_registers_is_refused(tmp_path):
    text = default_map_path().read_text()
    without = re.sub(r"\[holding\.amplitude_ramp_s\][^\[]*", "", text)
    path = tmp_path / "map.toml"
    path.write_text(without)
    with pytest.raises(RegisterMapError, match=r"amplitude_update needs all of \['amplitude_ramp_s'"):
        load_register_map(path)
    assert load_register_map().amplitude_updates


def test_an_update_beyond_the_soft_limits_is_refused_before_a_write():
    limits = BenchLimits(stroke_mm=5.0)
    with pytest.raises(LimitError, match="stroke"):
        AmplitudeUpdate(4.0, 0.1, mean_mm=1.5).registers(limits)
    with pytest.raises(LimitError, match=r"ramp_s=0\.05 below the minimum taper"):
        AmplitudeUpdate(1.0, 0.05).registers(limits)
    registers = AmplitudeUpdate(3.0, 0.2).registers(limits)
    assert registers == {"amplitude_update_mm": 3.0, "amplitude_ramp_s": 0.2}


async def test_the_client_names_the_controllers_refusal(client, controller):
    with pytest.raises(CommandRejectedError, match="amplitude update: NOT_ALLOWED_IN_STATE"):
        await client.update_amplitude(AmplitudeUpdate(1.0, 0.1))
    before = controller.writes_received
    with pytest.raises(LimitError):
        await client.update_amplitude(AmplitudeUpdate(100.0, 0.1))
    assert controller.writes_received == before


def map_without_updates(tmp_path: Path) -> Path:
    """The shipped map without its optional registers (they share the update's ramp)."""
    text = default_map_path().read_text()
    names = r"amplitude_update_mm|amplitude_ramp_s|notch_\w+|frequency_update_hz"
    text = re.sub(rf"\[holding\.({names})\][^\[]*", "", text)
    path = tmp_path / "no_updates.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def held_and_fallback(tmp_path_factory) -> dict[str, Path]:
    """A short grid through 40-70 Hz at 2 mm on the simulated lab: held within the dwell, and on a
    controller whose map has no amplitude update (the bench falls back to repeats)."""
    folder = tmp_path_factory.mktemp("held")
    # the paper grid's 1 s of measuring: the hold outlasts the unpaced bench's lead on the engine
    # (a few tenths of a second), in which an update must land
    sequence = grid_sequence((20.0, 40.0, 55.0, 70.0), 2.0, measure_min_s=1.0, taper_s=0.2)
    files = {}
    for name, text in (
        ("held", ""),
        ("fallback", f'[actuator]\nregister_map = "{map_without_updates(folder)}"\n'),
    ):
        path = folder / f"{name}.h5"
        with lab_campaign(bench_config(folder, text, f"{name}.toml"), sequence, path) as campaign:
            campaign.start()
            assert campaign.wait().status == "complete"
        files[name] = path
    return files


def test_held_within_the_dwell_every_point_is_done_at_its_first_attempt_within_1_percent(
    held_and_fallback,
):
    with open_campaign(held_and_fallback["held"]) as campaign:
        (run,) = campaign.runs
        points = run.points
        status = np.asarray(run.channels["status"])
        records = run.dwell_records()
        steps = [e for e in run.events if e.kind == "amplitude"]
    # on an idle host every point is done at its first attempt; on a starved one the unpaced bench
    # runs ahead of the engine and an update can land after its hold: the controller refuses it and
    # the repeat takes over (the fallback), which is the only way a point may be repeated here
    repeated = [p for p in points if p.status != "done"]
    refused = {e.fields["index"] for e in steps if e.fields.get("refusal")}
    assert all(p.status == "repeated" and p.index in refused for p in repeated), (repeated, refused)
    points = [p for p in points if p.status == "done"]
    assert [p.index for p in points] == list(range(4))
    for p in points:
        assert abs(p.achieved_amplitude_mm / p.amplitude_mm - 1) <= 0.01, p
    steps = [e for e in steps if any(p.start_sample <= e.sample <= p.end_sample for p in points)]
    updated = [p for p in points if p.amplitude_updates]
    assert {p.freq_hz for p in updated} >= {55.0, 70.0}  # +7 and +12 % uncorrected
    for p, record in zip(points, records, strict=True):
        assert p.measure_start_sample == -1  # measured as any dwell: its hold after its settling
        if not p.amplitude_updates:
            assert math.isnan(p.held_amplitude_mm)
            continue
        # each update's ramp shows as the hold bit low between the taper-in and the hold: the
        # point's hold is the constant-amplitude part after the last ramp, as long as the dwell's
        # planned hold, and the analysis is given that part
        held = (status[p.start_sample : p.hold_end_sample] & int(Status.AMPLITUDE_HOLD)) != 0
        rises = np.flatnonzero(np.diff(held.astype(int)) == 1) + 1 + p.start_sample
        assert len(rises) == p.amplitude_updates + 1 and rises[-1] == p.hold_start_sample
        assert p.hold_end_sample - p.hold_start_sample == pytest.approx(1100, abs=2)  # 0.1 + 1.0 s
        if p.freq_hz >= 40:  # the servo overshoots there: less command
            assert p.held_amplitude_mm < p.commanded_amplitude_mm
        assert p.start_sample + round(record.hold_s[0] * 1000) == p.hold_start_sample
    # the history: every look at a point's amplitude, each update with the amplitude it sent
    assert len(steps) == len(points) + sum(p.amplitude_updates for p in points)
    for p in updated:
        sent = [s.fields["updated_mm"] for s in steps if s.fields["index"] == p.index]
        sent = [mm for mm in sent if not math.isnan(mm)]
        assert len(sent) == p.amplitude_updates and sent[-1] == pytest.approx(p.held_amplitude_mm)


def test_without_the_update_registers_the_bench_corrects_by_repeats(held_and_fallback):
    with open_campaign(held_and_fallback["fallback"]) as campaign:
        (run,) = campaign.runs
        points = run.points
        events = [e for e in run.events if e.kind == "amplitude"]
    assert not events and not any(p.amplitude_updates for p in points)
    repeated = {p.freq_hz for p in points if p.status == "repeated"}
    assert repeated >= {55.0, 70.0}
    for p in points:
        if p.status == "done":
            assert abs(p.achieved_amplitude_mm / p.amplitude_mm - 1) <= 0.02, p


def test_an_update_the_soft_limits_refuse_leaves_the_point_to_the_amplitude_control(tmp_path):
    """At 20 Hz the actuator falls 0.6 % short of 2 mm; the stroke is 2 mm: the update up is not
    sent (it would pass the soft limit), which is noted with the point, and the point stands (within
    2 %, no repeat)."""
    sequence = grid_sequence((20.0,), 2.0, measure_min_s=0.3, taper_s=0.2)
    config = bench_config(tmp_path, "[limits]\nstroke_mm = 2.0\n")
    with lab_campaign(config, sequence, tmp_path / "c.h5") as campaign:
        campaign.start()
        assert campaign.wait().status == "complete"
    with open_campaign(tmp_path / "c.h5") as f:
        (point,) = f.runs[0].points
    assert (point.status, point.attempt, point.amplitude_updates) == ("done", 1, 0)
    assert point.note == "the update to 2.012 mm exceeds the 2 mm limit"


def test_a_version_2_file_written_before_the_held_amplitude_reads_with_its_defaults(
    held_and_fallback, tmp_path
):
    path = tmp_path / "older.h5"
    path.write_bytes(held_and_fallback["held"].read_bytes())
    with h5py.File(path, "r+") as f:
        (group,) = f["runs"].values()
        table = group["points"][()]
        names = [n for n in table.dtype.names if n not in ("amplitude_updates", "held_amplitude_mm")]
        older = np.zeros(len(table), [(n, table.dtype[n]) for n in names])
        for name in names:
            older[name] = table[name]
        del group["points"]
        group.create_dataset("points", data=older, maxshape=(None,), chunks=(64,))
    with open_campaign(path) as campaign:
        points = campaign.runs[0].points
    assert all(p.amplitude_updates == 0 and math.isnan(p.held_amplitude_mm) for p in points)
    assert len(points) >= 4  # every attempt's row (a repeat on a starved host adds one)


PAPER_SUBSET = (
    (1.5, 5.0, (37.0, 40.0, 43.0, 46.0, 50.0, 55.0, 60.0, 65.0, 70.0)),
    (3.5, 2.0, (40.0, 46.0, 55.0, 70.0)),
)


@pytest.mark.validation
@pytest.mark.slow
def test_the_paper_campaign_subset_repeats_no_point_and_holds_40_to_70_hz_within_2_percent(tmp_path):
    """The paper shaker grids' 40-70 Hz points where the servo is furthest off: the 5 mm grid at
    1.5 bar (its amplitude lowered by the velocity and acceleration maxima from 50 Hz, the valve
    flow-limited at 46-55 Hz) and the 2 mm grid at 3.5 bar. The whole campaign's figure (211 points,
    the paper grids' timing) is the benchmark's (benchmarks/amplitude_hold.py).

    The holds are 2.2 s, not the paper grids' 1.2 s: the unpaced simulated bench waits for its host
    only once a few blocks of frames are queued between them (the engine's block, its queue, the
    reader's, the pty's kernel buffers), so beside busy processes it runs up to about 1 s of samples
    ahead of the engine, and an update decided 0.1 s into a 1.2 s hold then reached the controller
    after the hold (refused, the point repeated: 1 run in 3 beside eight busy processes)."""
    steps: list = [Hydraulics("low"), Hydraulics("high")]
    for pressure, amplitude, freqs in PAPER_SUBSET:
        steps += [
            Hydraulics("low"),
            Prompt(
                f"p{pressure}", "set", "number", "bar", 0.5, 4.5, action="set_tyre_pressure", target=pressure
            ),
            Hydraulics("high"),
            Tare(),
            DwellGrid(
                freqs, (amplitude,), measure_min_s=2.0, max_velocity_mm_s=1500, max_acceleration_m_s2=500
            ),
        ]
    sequence = Sequence("subset", "", tuple(steps), "<test>")
    with lab_campaign(bench_config(tmp_path), sequence, tmp_path / "c.h5") as campaign:
        campaign.start()
        assert campaign.wait().status == "complete"
    with open_campaign(tmp_path / "c.h5") as f:
        points = [p for run in f.runs for p in run.points]
    assert all(p.status == "done" and p.attempt == 1 for p in points), [
        (p.freq_hz, p.status) for p in points if p.attempt > 1
    ]
    assert len(points) == sum(len(freqs) for _, _, freqs in PAPER_SUBSET)
    errors = [abs(p.achieved_amplitude_mm / p.amplitude_mm - 1) for p in points]
    assert max(errors) <= 0.02, errors
