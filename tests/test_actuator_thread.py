"""The engine's blocking actuator over Modbus TCP to the simulated controller: after a lost link
the fault stays until the operator resets, and the reset reconnects and beats again, so the next run
is guarded by the watchdog; a hydraulics command whose reply comes after the client's timeout is
settled by the controller's state, not failed (nor re-sent)."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from bench.app.actuator_thread import ControllerReadback, ThreadedActuator
from bench.app.simulated import SimulatedLab, SimulatedLabSettings
from bench.engine import events as ev
from bench.engine.interlocks import ControllerInterlock, Observation, trips
from bench.engine.stops import RunStoppedError
from drivers.actuator import DEFAULT_TIMEOUT_S, ActuatorClient, ActuatorStatus
from drivers.errors import CommandOutcomeUnknownError
from drivers.register_map import ControllerState, ErrorCode, InterlockFlag
from drivers.setpoints import DwellSetpoint
from sequences.limits import BenchLimits
from tests.waiting import wait_until


def test_reset_after_a_lost_link_reconnects_and_restarts_the_heartbeat():
    with SimulatedLab(SimulatedLabSettings(paced=True)) as lab:
        host, port = lab.address
        actuator = ThreadedActuator(lambda: ActuatorClient.tcp(host, port, limits=BenchLimits()))
        try:
            actuator.connect(heartbeat_period_s=0.05, watchdog_ms=1200)
            assert actuator.link_fault() is None
            actuator.set_hydraulics("low")
            actuator.set_hydraulics("high")
            actuator.configure(DwellSetpoint(freq_hz=10.0, amplitude_mm=1.0, taper_in_s=0.2, taper_out_s=0.2))
            actuator.start()  # a dwell until stopped
            lab.drop_controller_link()
            wait_until(lambda: actuator.link_fault() is not None, 10.0, "the link fault")
            controller = lab.bench.controller
            wait_until(
                lambda: controller.state is ControllerState.INTERLOCK, 10.0, "the watchdog to stop the dwell"
            )
            assert InterlockFlag.WATCHDOG in controller.flags
            assert actuator.link_fault() is not None  # it stays until the operator resets
            actuator.reset_interlock()
            assert actuator.link_fault() is None
            assert actuator.read_status().status.state is ControllerState.HYDRAULICS_LOW
            beats = actuator.client.heartbeat_failures
            echo = actuator.read_status().status.heartbeat_echo
            wait_until(lambda: actuator.read_status().status.heartbeat_echo != echo, 5.0, "a new heartbeat")
            assert actuator.client.heartbeat_failures == beats
        finally:
            actuator.close()


#: A reply this late (s) has timed out at the client: twice its reply timeout.
LATE_S = 2 * DEFAULT_TIMEOUT_S


@contextmanager
def quiet_actuator(lab: SimulatedLab) -> Iterator[ThreadedActuator]:
    """The actuator connected without a heartbeat: the next request after a call is the test's own."""
    actuator = ThreadedActuator(lambda: ActuatorClient.tcp(*lab.address), heartbeat=False)
    try:
        actuator.connect()
        yield actuator
    finally:
        actuator.close()


def test_a_late_hydraulics_reply_is_settled_by_the_status():
    """The write lands but its acknowledgement comes after the timeout: the outcome is unknown to
    the client, the status read after it shows the commanded state, so the command stands; it went
    to the controller once (never re-sent)."""
    with SimulatedLab() as lab, quiet_actuator(lab) as actuator:
        actuator.set_hydraulics("low")
        writes = lab.server.writes_received
        lab.server.faults.delay_next, lab.server.faults.delay_s = 1, LATE_S
        actuator.set_hydraulics("high")
        assert lab.server.faults.delay_next == 0, "the command's reply was the late one"
        assert actuator.read_status().status.state is ControllerState.HYDRAULICS_HIGH
        assert lab.server.writes_received == writes + 1


def test_a_late_reply_to_a_refused_hydraulics_command_names_the_state():
    """A late reply whose write did not take effect (refused): the outcome stays an error, typed
    as unknown and naming the state the controller reads, not a call that took too long."""
    with SimulatedLab() as lab, quiet_actuator(lab) as actuator:
        actuator.set_hydraulics("low")
        faults = lab.server.faults
        faults.delay_next, faults.delay_s, faults.exception_next = 1, LATE_S, 1
        with pytest.raises(CommandOutcomeUnknownError, match=r"hydraulics high: .*reads hydraulics_low"):
            actuator.set_hydraulics("high")
        assert actuator.read_status().status.state is ControllerState.HYDRAULICS_LOW


def test_late_replies_to_start_and_stop_are_settled_by_the_status():
    """START whose acknowledgement comes late: the controller moves, so it started; STOP likewise:
    it tapers (the watchdog, armed at power-up with 1.5 s and unfed here, has not tripped)."""
    with SimulatedLab() as lab, quiet_actuator(lab) as actuator:
        actuator.set_hydraulics("low")
        actuator.set_hydraulics("high")
        actuator.configure(DwellSetpoint(freq_hz=10.0, amplitude_mm=1.0, taper_in_s=0.2, taper_out_s=0.5))
        faults = lab.server.faults
        faults.delay_next, faults.delay_s = 1, LATE_S
        actuator.start()
        assert actuator.read_status().status.state is ControllerState.RUNNING
        faults.delay_next = 1
        actuator.stop()
        assert faults.delay_next == 0, "the stop's reply was the late one"
        assert actuator.read_status().status.state is not ControllerState.RUNNING
        assert InterlockFlag.WATCHDOG not in lab.bench.controller.flags


def _interlocked(lab: SimulatedLab, actuator: ThreadedActuator) -> None:
    """The controller interlocked by its own watchdog (a dwell left unbeaten), at rest."""
    actuator.set_hydraulics("low")
    actuator.set_hydraulics("high")
    actuator.configure(DwellSetpoint(freq_hz=10.0, amplitude_mm=1.0, taper_in_s=0.2, taper_out_s=0.2))
    lab.bench.controller.write_setpoints({"watchdog_ms": 100})
    actuator.start()
    controller = lab.bench.controller
    wait_until(lambda: controller.state is ControllerState.INTERLOCK, 10.0, "the watchdog's interlock")
    wait_until(lambda: not actuator.read_status().status.moving, 10.0, "the taper's end")


@pytest.mark.parametrize("applied", [True, False], ids=["reset applied", "reset not applied"])
def test_a_reset_whose_reply_is_late_is_settled_by_the_status_and_sent_again_if_not_taken(applied, caplog):
    """A starved host misses the reset's reply: the status read after it decides. Taken, the reset
    stands (sent once); not taken (still interlocked), it is sent once more and the controller is
    released either way, so the engine is not left failed by a reply it did not see in time."""
    with SimulatedLab() as lab, quiet_actuator(lab) as actuator:
        _interlocked(lab, actuator)
        faults = lab.server.faults
        faults.delay_next, faults.delay_s, faults.exception_next = 1, LATE_S, 0 if applied else 1
        with caplog.at_level(logging.WARNING, logger="bench.app.actuator_thread"):
            actuator.reset_interlock()
        assert faults.delay_next == 0 and faults.exception_next == 0, "the reset's reply was the late one"
        assert actuator.read_status().status.state is ControllerState.HYDRAULICS_LOW
        assert not lab.bench.controller.flags
        (said,) = [r.getMessage() for r in caplog.records if r.getMessage().startswith("reset: ")]
        assert said.endswith("reads hydraulics_low: done" if applied else "still reads interlock: sent again")


def test_a_late_reply_to_a_setpoint_write_writes_the_setpoint_again_and_start_goes_through():
    """The first register write of a setpoint is acknowledged after the client's timeout: the
    client cannot tell whether it landed, so the whole setpoint is written once more (the same
    values: the controller ends as after one write) and the excitation then starts at it."""
    with SimulatedLab() as lab, quiet_actuator(lab) as actuator:
        actuator.set_hydraulics("low")
        actuator.set_hydraulics("high")
        writes = lab.server.writes_received
        lab.server.faults.delay_next, lab.server.faults.delay_s = 1, LATE_S
        actuator.configure(DwellSetpoint(freq_hz=12.0, amplitude_mm=1.0, taper_in_s=0.2, taper_out_s=0.2))
        assert lab.server.faults.delay_next == 0, "a setpoint write's reply was the late one"
        assert lab.server.writes_received > writes + 1, "the setpoint was written again"
        actuator.start()
        wait_until(
            lambda: actuator.read_status().status.state is ControllerState.RUNNING, 10.0, "the excitation"
        )
        assert lab.bench.controller.setpoints["frequency_hz"] == pytest.approx(12.0)
        actuator.stop()


@pytest.mark.parametrize(
    ("state", "flags", "reason"),
    [
        (ControllerState.INTERLOCK, InterlockFlag.WATCHDOG, "controller interlock: watchdog"),
        (ControllerState.ESTOP, InterlockFlag.ESTOP, "controller interlock: estop"),
        (ControllerState.ESTOP, InterlockFlag(0), "controller interlock: estop"),
        (
            ControllerState.INTERLOCK,
            InterlockFlag.DISPLACEMENT | InterlockFlag.FORCE,
            "controller interlock: displacement, force",
        ),
        (ControllerState.INTERLOCK, InterlockFlag(0), "controller interlock: no flag set"),
    ],
)
def test_the_controllers_interlock_reads_once_in_the_runs_reason(state, flags, reason):
    """The readback names what holds the controller, the engine's interlock names the controller:
    "controller interlock: watchdog", never "controller interlock: controller interlock: ..."."""
    status = ActuatorStatus(2, state, flags, ErrorCode.NONE, 0, 0, 0.0, 0.0, 0.0, 0.0, 0)
    seen = Observation({}, controller=ControllerReadback(status))
    (trip,) = trips((ControllerInterlock(),), seen)
    assert (
        RunStoppedError.interlock_tripped(ev.InterlockTripped(trip.name, trip.reason, "r")).reason == reason
    )


def test_a_controller_that_holds_nothing_gives_no_reason():
    status = ActuatorStatus(
        2, ControllerState.RUNNING, InterlockFlag(0), ErrorCode.NONE, 0, 0, 0.0, 0.0, 0.0, 0.0, 0
    )
    assert ControllerReadback(status).interlock_reason is None
