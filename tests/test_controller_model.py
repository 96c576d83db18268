"""The simulated controller's state machine, tapers, mean ramps, watchdog and interlocks, in samples.

No Modbus and no wall clock: the model runs on its own sample clock and is fed the displacement it
commands as the measured one (an ideal actuator), or a measurement a test chooses.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.register_map import Command, ControllerState, ErrorCode, InterlockFlag, WaveformCode
from simulators.controller_model import MAX_FREQUENCY_HZ, MIN_TAPER_S, POWER_UP, ControllerModel
from simulators.function_generator import MEAN_RATE_MM_S

RATE = 10_000.0  # internal samples per second
OVERSAMPLING = 10  # measured values at 1 kHz
BLOCK = 100  # internal samples per step (10 ms)
S = ControllerState
C = Command

DWELL = {
    "waveform": WaveformCode.SINE_DWELL, "amplitude_mm": 2.0, "frequency_hz": 10.0, "dwell_s": 0.0,
    "taper_in_s": 0.5, "taper_out_s": 0.4, "mean_mm": 0.0, "watchdog_ms": 0,
}  # fmt: skip


def run(
    model: ControllerModel, seconds: float, *, z_extra_m: float = 0.0, force_n: float = 0.0
) -> np.ndarray:
    """Advance ``seconds`` in blocks, measuring the command plus ``z_extra_m``; return the command."""
    out = []
    for _ in range(round(seconds * RATE / BLOCK)):
        command = model.command_block(BLOCK)
        z = command[OVERSAMPLING - 1 :: OVERSAMPLING] + z_extra_m
        model.observe(z, np.full(len(z), force_n), RATE / OVERSAMPLING)
        model.measure_amplitude(z)  # the measured rate is the controller's 1 kHz clock
        out.append(command)
    return np.concatenate(out) if out else np.zeros(0)


def run_until(model: ControllerModel, state: ControllerState, max_s: float) -> np.ndarray:
    """Advance block by block until ``state``; fail after ``max_s``; return the command."""
    out = []
    for _ in range(round(max_s * RATE / BLOCK)):
        out.append(run(model, BLOCK / RATE))
        if model.state == state:
            return np.concatenate(out)
    raise AssertionError(f"not {state.name} after {max_s} s (state {model.state.name})")


def act(model: ControllerModel, *commands: Command) -> None:
    for command in commands:
        assert model.command(command) is None, command.name


def armed(setpoints: dict | None = None) -> ControllerModel:
    model = ControllerModel(RATE)
    act(model, C.HYDRAULICS_LOW, C.HYDRAULICS_HIGH)
    assert model.write_setpoints(setpoints or DWELL) is None
    return model


#: commands that bring a new controller into a state (INTERLOCK: running, then a force trip)
PATHS = {
    S.OFF: (),
    S.HYDRAULICS_LOW: (C.HYDRAULICS_LOW,),
    S.HYDRAULICS_HIGH: (C.HYDRAULICS_LOW, C.HYDRAULICS_HIGH),
    S.RUNNING: (C.HYDRAULICS_LOW, C.HYDRAULICS_HIGH, C.START),
    S.TAPERING: (C.HYDRAULICS_LOW, C.HYDRAULICS_HIGH, C.START, C.STOP),
    S.INTERLOCK: (C.HYDRAULICS_LOW, C.HYDRAULICS_HIGH, C.START),
    S.ESTOP: (C.ESTOP,),
}


def in_state(state: ControllerState) -> ControllerModel:
    """A model brought into ``state`` through commands and measurements only."""
    model = ControllerModel(RATE)
    model.write_setpoints({**DWELL, "force_limit_n": 1000.0})
    for command in PATHS[state]:
        act(model, command)
        run(model, 0.05)
    if state is S.INTERLOCK:
        run(model, 0.01, force_n=2000.0)  # trips the force limit
        run_until(model, S.INTERLOCK, 1.0)
    return model


_ = None  # refused: NOT_ALLOWED_IN_STATE, state unchanged
#: state -> the state after each command (in Command order 1..7), None where it is refused
TRANSITIONS = {
    #                   OFF    LOW    HIGH    START      STOP         ESTOP    RESET
    S.OFF:             (S.OFF, S.HYDRAULICS_LOW, _, _, S.OFF, S.ESTOP, _),
    S.HYDRAULICS_LOW:  (S.OFF, S.HYDRAULICS_LOW, S.HYDRAULICS_HIGH, _, S.HYDRAULICS_LOW, S.ESTOP, _),
    S.HYDRAULICS_HIGH: (S.OFF, S.HYDRAULICS_LOW, S.HYDRAULICS_HIGH, S.RUNNING, S.HYDRAULICS_HIGH, S.ESTOP, _),
    S.RUNNING:         (_, _, _, _, S.TAPERING, S.ESTOP, _),
    S.TAPERING:        (_, _, _, _, S.TAPERING, S.ESTOP, _),
    S.INTERLOCK:       (_, _, _, _, S.INTERLOCK, S.ESTOP, S.HYDRAULICS_LOW),
    S.ESTOP:           (_, _, _, _, S.ESTOP, S.ESTOP, S.HYDRAULICS_LOW),
}  # fmt: skip


@pytest.mark.parametrize(
    ("state", "command", "expected"),
    [(state, cmd, after) for state, row in TRANSITIONS.items() for cmd, after in zip(C, row, strict=True)],
    ids=lambda v: getattr(v, "name", str(v)),
)
def test_transition_table(state, command, expected):
    model = in_state(state)
    assert model.state == state
    refused = model.command(command)
    if expected is None:
        assert refused == ErrorCode.NOT_ALLOWED_IN_STATE
        assert model.error == ErrorCode.NOT_ALLOWED_IN_STATE
        assert model.state == state
    else:
        assert refused is None
        assert model.error == ErrorCode.NONE
        assert model.state == expected


def test_the_table_covers_every_state_and_command():
    assert set(TRANSITIONS) == set(ControllerState)
    assert all(len(row) == len(Command) for row in TRANSITIONS.values())


@pytest.mark.parametrize("state", list(ControllerState), ids=lambda s: s.name)
def test_unknown_command_is_refused_in_every_state(state):
    model = in_state(state)
    assert model.command(99) == ErrorCode.UNKNOWN_COMMAND
    assert model.state == state


def test_taper_in_is_a_raised_cosine():
    model = armed()
    act(model, C.START)
    cmd = run(model, 1.0)
    t = np.arange(len(cmd)) / RATE
    ramp = t < 0.5
    envelope = np.where(ramp, 0.5 - 0.5 * np.cos(np.pi * t / 0.5), 1.0)
    np.testing.assert_allclose(cmd, 0.002 * envelope * np.sin(2 * np.pi * 10.0 * t), atol=1e-12)


def test_stop_tapers_the_excitation_out_with_a_raised_cosine_never_a_step():
    model = armed()
    act(model, C.START)
    before = run(model, 1.013)  # stop between zero crossings, where a step would be largest
    act(model, C.STOP)
    assert model.state == S.TAPERING
    after = run_until(model, S.HYDRAULICS_HIGH, 1.0)
    t = (len(before) + np.arange(len(after))) / RATE
    tau = np.arange(len(after)) / RATE
    envelope = np.where(tau < 0.4, 0.5 + 0.5 * np.cos(np.pi * tau / 0.4), 0.0)
    np.testing.assert_allclose(after, 0.002 * envelope * np.sin(2 * np.pi * 10.0 * t), atol=1e-12)
    # at rest within the taper time (plus the block the state is checked on)
    assert len(after) <= (0.4 * RATE) + BLOCK
    whole = np.concatenate([before, after])
    steepest = 0.002 * (2 * np.pi * 10.0 + np.pi / (2 * 0.4)) / RATE
    assert np.max(np.abs(np.diff(whole))) <= steepest * (1 + 1e-9)
    assert whole[-1] == 0.0


def test_sweep_ends_by_itself_and_comes_to_rest():
    model = armed({
        "waveform": WaveformCode.LOG_SWEEP, "amplitude_mm": 1.0, "sweep_start_hz": 2.0,
        "sweep_end_hz": 8.0, "sweep_duration_s": 0.8, "taper_in_s": 0.2, "taper_out_s": 0.2,
    })  # fmt: skip
    act(model, C.START)
    cmd = run_until(model, S.HYDRAULICS_HIGH, 2.0)
    assert len(cmd) <= 0.8 * RATE + BLOCK
    assert model.flags == InterlockFlag(0)


def test_mean_position_ramps_in_and_out_at_the_stated_rate():
    model = armed({**DWELL, "waveform": WaveformCode.STATIC, "mean_mm": 5.0})
    act(model, C.START)
    ramp_s = 5.0 / MEAN_RATE_MM_S
    cmd = run(model, ramp_s + 0.2)
    t = np.arange(len(cmd)) / RATE
    expected = 0.005 * np.where(t < ramp_s, 0.5 - 0.5 * np.cos(np.pi * t / ramp_s), 1.0)
    np.testing.assert_allclose(cmd, expected, atol=1e-12)
    peak_speed_mm_s = np.max(np.abs(np.diff(cmd))) * RATE * 1000
    assert peak_speed_mm_s <= math.pi / 2 * MEAN_RATE_MM_S * (1 + 1e-6)
    assert model.state == S.RUNNING  # a static waveform holds the mean until stopped
    act(model, C.STOP)
    back = run_until(model, S.HYDRAULICS_HIGH, 2 * ramp_s)
    assert len(back) <= ramp_s * RATE + BLOCK
    assert back[-1] == 0.0
    assert np.max(np.abs(np.diff(back))) * RATE * 1000 <= math.pi / 2 * MEAN_RATE_MM_S * (1 + 1e-6)


def test_stop_during_the_mean_ramp_returns_from_where_the_mean_is():
    model = armed({**DWELL, "waveform": WaveformCode.STATIC, "mean_mm": 5.0})
    act(model, C.START)
    out = run(model, 0.2)
    act(model, C.STOP)
    back = run_until(model, S.HYDRAULICS_HIGH, 1.0)
    assert len(back) <= abs(out[-1]) * 1000 / MEAN_RATE_MM_S * RATE + BLOCK
    whole = np.concatenate([out, back])
    assert np.max(np.abs(np.diff(whole))) * RATE * 1000 <= math.pi / 2 * MEAN_RATE_MM_S * (1 + 1e-6)
    assert whole[-1] == 0.0


def test_displacement_limit_is_measured_from_the_present_mean():
    # a 5 mm mean with a 1 mm limit: following the ramp closely must not trip
    model = armed({**DWELL, "amplitude_mm": 0.5, "mean_mm": 5.0, "displacement_limit_mm": 1.0})
    act(model, C.START)
    run(model, 1.5)
    assert model.state == S.RUNNING
    assert model.flags == InterlockFlag(0)
    # a measured excursion of 1.2 mm beyond the commanded motion does
    run(model, 0.01, z_extra_m=0.0012)
    assert model.flags == InterlockFlag.DISPLACEMENT
    assert model.state == S.TAPERING
    run_until(model, S.INTERLOCK, 2.0)
    assert model.generator.at_rest


def test_force_limit_trips_and_limits_are_not_checked_at_rest():
    model = armed({**DWELL, "force_limit_n": 1000.0})
    run(model, 0.1, force_n=5000.0)  # not moving: no interlock
    assert model.state == S.HYDRAULICS_HIGH and model.flags == InterlockFlag(0)
    act(model, C.START)
    run(model, 0.2)
    run(model, 0.01, force_n=-1500.0)
    assert model.flags == InterlockFlag.FORCE
    cmd = run_until(model, S.INTERLOCK, 2.0)
    assert len(cmd) <= 0.4 * RATE + BLOCK
    assert model.command(C.START) == ErrorCode.NOT_ALLOWED_IN_STATE
    act(model, C.RESET_INTERLOCK)
    assert model.state == S.HYDRAULICS_LOW and model.flags == InterlockFlag(0)


def test_watchdog_tapers_to_rest_within_watchdog_plus_taper_time():
    watchdog_s, taper_s = 0.2, 0.4
    model = armed({**DWELL, "watchdog_ms": watchdog_s * 1000})
    act(model, C.START)
    for beat in range(1, 21):  # a heartbeat every 50 ms keeps it running for a second
        run(model, 0.05)
        assert model.write_setpoints({"heartbeat": beat}) is None
    assert model.state == S.RUNNING
    lost_at = model.generator.n
    run(model, watchdog_s - 0.01)
    assert model.state == S.RUNNING  # not before the watchdog time
    run_until(model, S.INTERLOCK, 2.0)
    at_rest_after_s = (model.generator.n - lost_at) / RATE
    assert at_rest_after_s <= watchdog_s + taper_s + 2 * BLOCK / RATE
    assert model.flags == InterlockFlag.WATCHDOG
    assert model.generator.last_m == 0.0


def test_a_frozen_heartbeat_counter_does_not_hold_off_the_watchdog():
    watchdog_s = 0.1
    model = armed({**DWELL, "watchdog_ms": watchdog_s * 1000, "heartbeat": 7})
    act(model, C.START)
    started_at = model.generator.n
    while model.state == S.RUNNING and model.generator.n - started_at < RATE:
        run(model, 0.02)
        assert model.write_setpoints({"heartbeat": 7}) is None  # written, but never changing
    assert model.flags == InterlockFlag.WATCHDOG
    assert (model.generator.n - started_at) / RATE <= watchdog_s + 2 * BLOCK / RATE


def test_watchdog_disabled_by_zero_and_idle_when_not_running():
    model = armed({**DWELL, "watchdog_ms": 0})
    act(model, C.START)
    run(model, 1.0)
    assert model.state == S.RUNNING
    model.write_setpoints({"watchdog_ms": 100})
    act(model, C.STOP)
    run_until(model, S.HYDRAULICS_HIGH, 1.0)  # a stop under way finishes normally
    run(model, 0.5)
    assert model.state == S.HYDRAULICS_HIGH and model.flags == InterlockFlag(0)


def test_estop_freezes_and_the_release_ramps_back_to_rest():
    model = armed({**DWELL, "mean_mm": 3.0})
    act(model, C.START)
    running = run(model, 1.0)
    frozen_m = running[-1]
    assert abs(frozen_m) > 0.002  # mean plus part of the sine
    act(model, C.ESTOP)
    held = run(model, 0.3)
    assert np.all(held == frozen_m)  # no taper: the command is frozen
    assert model.flags == InterlockFlag.ESTOP
    assert model.command(C.START) == ErrorCode.NOT_ALLOWED_IN_STATE
    act(model, C.RESET_INTERLOCK)
    assert model.state == S.TAPERING and model.flags == InterlockFlag(0)
    back = run_until(model, S.HYDRAULICS_LOW, 2.0)
    ramp_s = abs(frozen_m) * 1000 / MEAN_RATE_MM_S
    assert len(back) <= ramp_s * RATE + BLOCK
    whole = np.concatenate([held, back])
    assert np.max(np.abs(np.diff(whole))) * RATE * 1000 <= math.pi / 2 * MEAN_RATE_MM_S * (1 + 1e-6)
    assert back[-1] == 0.0


def test_estop_during_the_release_freezes_again():
    model = armed({**DWELL, "mean_mm": 4.0})
    act(model, C.START)
    run(model, 1.0)
    act(model, C.ESTOP, C.RESET_INTERLOCK)
    partway = run(model, 0.1)[-1]
    act(model, C.ESTOP)
    assert np.all(run(model, 0.1) == partway)
    act(model, C.RESET_INTERLOCK)
    run_until(model, S.HYDRAULICS_LOW, 2.0)


@pytest.mark.parametrize(
    "values",
    [
        {"frequency_hz": float("nan")},
        {"frequency_hz": 0.0},
        {"amplitude_mm": -1.0},
        {"taper_out_s": 0.0},
        {"taper_in_s": MIN_TAPER_S / 2},
        {"waveform": 7},
        {"mean_mm": 2.0, "dwell_s": -1.0},  # one bad value: nothing of the write is applied
        # beyond the hardware: 50 mm stroke, 50 kN
        {"mean_mm": 50.5},
        {"mean_mm": -51.0},
        {"amplitude_mm": 50.5},
        {"displacement_limit_mm": 60.0},
        {"force_limit_n": 60_000.0},
    ],
)
def test_invalid_setpoints_are_refused_and_nothing_is_applied(values):
    model = armed()
    before = dict(model.setpoints)
    assert model.write_setpoints(values) == ErrorCode.INVALID_SETPOINT
    assert model.error == ErrorCode.INVALID_SETPOINT
    assert model.setpoints == before


def test_an_accepted_write_clears_the_last_refusal():
    model = armed()
    assert model.write_setpoints({"frequency_hz": 0.0}) == ErrorCode.INVALID_SETPOINT
    assert model.write_setpoints({"frequency_hz": 5.0}) is None
    assert model.error == ErrorCode.NONE


def test_start_refused_when_mean_plus_amplitude_leaves_the_stroke():
    model = armed({**DWELL, "mean_mm": 45.0, "amplitude_mm": 30.0})
    assert model.command(C.START) == ErrorCode.INVALID_SETPOINT
    assert model.state == S.HYDRAULICS_HIGH and model.generator.at_rest
    assert model.write_setpoints({"mean_mm": -20.0}) is None  # |-20| + 30 = 50 mm: the whole stroke
    act(model, C.START)
    assert model.state == S.RUNNING


def test_displacement_beyond_the_stroke_trips_whatever_the_mean_and_the_interlock_limit():
    # 45 mm mean and 4 mm amplitude fit; no host limit set (0: the stroke, measured from the mean)
    model = armed({**DWELL, "mean_mm": 45.0, "amplitude_mm": 4.0, "displacement_limit_mm": 0.0})
    act(model, C.START)
    run(model, 45.0 / MEAN_RATE_MM_S + DWELL["taper_in_s"] + 0.2)
    assert model.state == S.RUNNING and model.flags == InterlockFlag(0)
    # 2 mm beyond the command: 6 mm from the mean, but 51 mm from the centre of the stroke
    run(model, 0.1, z_extra_m=0.002)
    assert model.flags == InterlockFlag.DISPLACEMENT
    assert model.state == S.TAPERING


def test_setpoints_written_while_running_wait_for_the_next_start():
    model = armed()
    act(model, C.START)
    run(model, 0.6)
    model.write_setpoints({"amplitude_mm": 4.0, "mean_mm": 3.0})
    cmd = run(model, 0.5)
    assert np.max(np.abs(cmd)) == pytest.approx(0.002, rel=1e-3)


def test_readbacks_count_cycles_amplitude_and_the_controller_clock():
    model = armed()
    act(model, C.START)
    run(model, 2.0)
    rb = model.readback
    assert rb.frequency_hz == 10.0
    assert rb.cycle_count == 20
    assert rb.achieved_amplitude_mm == pytest.approx(2.0, rel=1e-3)
    assert rb.sample_count == 2000  # 1 kHz


@pytest.mark.parametrize(
    "values",
    [
        {"frequency_hz": MAX_FREQUENCY_HZ * 1.01},
        {"frequency_hz": 1e6},
        {"sweep_end_hz": MAX_FREQUENCY_HZ + 1.0},
        {"displacement_limit_mm": -1.0},
        {"force_limit_n": -100.0},
        {"channel_mask": 0},
        {"channel_mask": 0xFFF0},  # posts 5..16: none exists
    ],
)
def test_frequency_ceiling_negative_limits_and_empty_masks_are_refused(values):
    model = armed()
    before = dict(model.setpoints)
    assert model.write_setpoints(values) == ErrorCode.INVALID_SETPOINT
    assert model.setpoints == before


def test_the_frequency_ceiling_itself_runs():
    model = armed({**DWELL, "frequency_hz": MAX_FREQUENCY_HZ, "amplitude_mm": 0.1})
    act(model, C.START)
    run(model, 0.6)
    assert model.readback.frequency_hz == MAX_FREQUENCY_HZ


def test_channel_mask_selects_the_posts_that_move():
    # a four-post controller: post 1 (the plant) moves only when its bit is set
    model = ControllerModel(RATE, posts=4)
    act(model, C.HYDRAULICS_LOW, C.HYDRAULICS_HIGH)
    assert model.write_setpoints({**DWELL, "channel_mask": 0b0010}) is None  # post 2 only
    act(model, C.START)
    assert np.all(run(model, 1.0) == 0.0)
    assert model.state == S.RUNNING
    act(model, C.STOP)
    run_until(model, S.HYDRAULICS_HIGH, 1.0)
    assert model.write_setpoints({"channel_mask": 0b0011}) is None
    act(model, C.START)
    assert np.max(np.abs(run(model, 1.0))) == pytest.approx(0.002, rel=1e-3)


def test_power_up_values_are_in_force_and_the_watchdog_is_armed():
    model = ControllerModel(RATE)
    assert model.setpoints == POWER_UP
    assert POWER_UP["watchdog_ms"] > 0
    act(model, C.HYDRAULICS_LOW, C.HYDRAULICS_HIGH, C.START)  # the power-up values run: hold the mean
    watchdog_s = POWER_UP["watchdog_ms"] / 1000
    run(model, watchdog_s - 0.02)
    assert model.state == S.RUNNING
    run(model, 0.02 + 2 * BLOCK / RATE)  # no heartbeat ever: the armed watchdog trips (checked per block)
    assert model.flags == InterlockFlag.WATCHDOG


def test_rewriting_watchdog_ms_while_running_does_not_restart_the_watchdog():
    watchdog_s = 0.2
    model = armed({**DWELL, "watchdog_ms": watchdog_s * 1000})
    act(model, C.START)
    blocks = 0
    while model.flags == InterlockFlag(0) and blocks < RATE / BLOCK:
        run(model, BLOCK / RATE)
        blocks += 1
        if blocks % 5 == 0:  # a host rewriting its configuration every 50 ms, never beating
            assert model.write_setpoints({"watchdog_ms": watchdog_s * 1000}) is None
    assert model.flags == InterlockFlag.WATCHDOG
    assert watchdog_s <= model.generator.n / RATE <= watchdog_s + 2 * BLOCK / RATE
