"""The engine's blocking actuator after a lost Modbus link: the fault stays until the operator
resets, and the reset reconnects and beats again, so the next run is guarded by the watchdog."""

from __future__ import annotations

from bench.app.actuator_thread import ThreadedActuator
from bench.app.simulated import SimulatedLab, SimulatedLabSettings
from drivers.actuator import ActuatorClient
from drivers.register_map import ControllerState, InterlockFlag
from drivers.setpoints import DwellSetpoint, SoftLimits
from tests.waiting import wait_until


def test_reset_after_a_lost_link_reconnects_and_restarts_the_heartbeat():
    with SimulatedLab(SimulatedLabSettings(paced=True)) as lab:
        host, port = lab.address
        actuator = ThreadedActuator(lambda: ActuatorClient.tcp(host, port, limits=SoftLimits()))
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
