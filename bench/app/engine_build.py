"""Building the run engine on an opened bench: channels, interlocks, sync bits and tare policy.

:func:`build_engine` turns the bench configuration into the :class:`~bench.engine.engine.Engine`'s
settings (the recorded channels and the calibration matrix, the host-side interlocks from the
bench's limits, the controller's sync bits in the WFS status word, the amplitude control's command
limit) and gives it the devices :func:`bench.app.devices.open_bench` opened. Front ends that keep
the bench open between sequences (the terminal UI) build the engine once; a command-line run builds
it for its one sequence (:mod:`bench.app.run`).
"""

from __future__ import annotations

from dataclasses import fields, replace

from bench.app.devices import BenchDevices
from bench.app.notching import ModelNotching
from bench.app.simulated import UNPACED_BACKLOG_S, UNPACED_WFS_SILENCE_S
from bench.config import BenchConfig
from bench.engine.amplitude import AmplitudeControl, FramesPresent
from bench.engine.amplitude_hold import AmplitudeHold
from bench.engine.channels import FrameChannels
from bench.engine.engine import Engine
from bench.engine.interlocks import standard_interlocks
from bench.engine.points import SyncBits
from drivers.wfs_frame import Status
from drivers.wfs_transform import LoadProcessor


def build_engine(config: BenchConfig, devices: BenchDevices) -> Engine:
    """The engine on ``devices`` with the configured channels, interlocks and tare policy (on the
    unpaced simulated bench, which waits for the engine: a short backlog, and a link silence
    limit of at least :data:`~bench.app.simulated.UNPACED_WFS_SILENCE_S`)."""
    unpaced = devices.lab is not None and not devices.lab.settings.paced
    timing = config.timing
    if unpaced:
        silence_s = max(timing.wfs_silence_s, UNPACED_WFS_SILENCE_S)
        timing = replace(timing, backlog_s=UNPACED_BACKLOG_S, wfs_silence_s=silence_s)
    channels = FrameChannels(config.aux, LoadProcessor(matrix=config.calibration.matrix_array()))
    return Engine(
        devices.actuator,
        devices.acquisition,
        devices.operator,
        channels=channels,
        interlocks=standard_interlocks(
            channels.recorded,
            config.limits,
            serial_timeout_s=timing.wfs_silence_s,
            actions={f.name: getattr(config.actions, f.name) for f in fields(config.actions)},
            response_limits=config.response_limits,
        ),
        sync_bits=SyncBits(int(Status.EXCITATION_ACTIVE), int(Status.AMPLITUDE_HOLD)),
        sample_rate_hz=float(config.wfs.rate_hz),
        amplitude_control=AmplitudeControl(
            tolerance=config.amplitude.tolerance,
            max_corrections=config.amplitude.max_repeats,
            max_command_mm=config.limits.stroke_mm,
            max_step_factor=config.amplitude.max_step_factor,
            command_margin=config.amplitude.command_margin,
            excursion_tolerance=config.amplitude.excursion_tolerance,
            excursion_action=config.amplitude.excursion_action,
        ),
        amplitude_hold=_amplitude_hold(config, devices),
        frames_present=FramesPresent(config.amplitude.max_missing_fraction, config.amplitude.min_cycles),
        notching=ModelNotching(config) if any(limit.notch for limit in config.response_limits) else None,
        tare=config.calibration.tare,
        bench_kind=config.kind,
        timing=timing,
    )


def _amplitude_hold(config: BenchConfig, devices: BenchDevices) -> AmplitudeHold | None:
    """The amplitude held within the dwell, as configured, where the controller takes amplitude
    updates (its register map names their registers); None: amplitudes are corrected by repeats."""
    settings = config.amplitude
    if not settings.hold_within_dwell or not devices.actuator.amplitude_updates:
        return None
    return AmplitudeHold(
        update_tolerance=settings.update_tolerance, max_updates=settings.max_updates, ramp_s=settings.ramp_s
    )
