"""The amplitude hold of one attempt at a fixed-timing dwell, wired to the bench: its updates go
to the actuator as amplitude updates, each look at the amplitude is checked for an excursion and
published (:class:`~bench.engine.events.AmplitudeChecked`). The hold itself, what it measures and
when it updates, is :class:`~bench.engine.amplitude_hold.HeldAmplitude`'s.
"""

from __future__ import annotations

import logging

from bench.engine import events as ev
from bench.engine.amplitude_hold import AmplitudeStep, HeldAmplitude
from bench.engine.recording import RunRecording
from bench.engine.run_context import RunContext
from drivers.errors import CommandOutcomeUnknownError, CommandRejectedError, LimitError
from drivers.setpoints import AmplitudeUpdate
from sequences import SineDwell

log = logging.getLogger(__name__)


def held_amplitude(
    context: RunContext,
    recording: RunRecording,
    dwell: SineDwell,
    *,
    index: int,
    attempt: int,
    command_mm: float,
) -> HeldAmplitude | None:
    """The amplitude hold of attempt ``attempt`` at point ``index``, a fixed-timing dwell started at
    ``command_mm`` (None: the engine holds none)."""
    settings = context.amplitude_hold
    if settings is None:
        return None
    mean_mm = context.mean_mm(dwell.mean_mm)

    def update(amplitude_mm: float) -> str | None:
        try:
            context.actuator.update_amplitude(AmplitudeUpdate(amplitude_mm, settings.ramp_s, mean_mm))
        except LimitError as exc:
            return f"refused by the soft limits: {exc}"
        except CommandOutcomeUnknownError as exc:
            log.warning("amplitude update: %s; the hold sync output tells whether it came", exc)
        except CommandRejectedError as exc:
            return str(exc)
        return None

    def checked(step: AmplitudeStep) -> None:
        if not step.lost:
            where = f"point {index} attempt {attempt}"
            recording.check_excursion(dwell.amplitude_mm, step.achieved_mm, where)
        context.publish(
            ev.AmplitudeChecked(
                recording.run_id,
                index,
                attempt,
                step.sample,
                dwell.amplitude_mm,
                step.achieved_mm,
                step.command_mm,
                step.updated_mm,
                step.refusal,
                step.frames_missing,
                step.lost,
            )
        )

    return HeldAmplitude(
        freq_hz=dwell.freq_hz,
        target_mm=dwell.amplitude_mm,
        command_mm=command_mm,
        settle_s=dwell.settle_s,
        hold_s=dwell.hold_s,
        settings=settings,
        control=context.amplitude_control,
        present=context.frames_present,
        sample_rate_hz=context.sample_rate_hz,
        displacement=context.channels.displacement,
        hold_bit=context.sync_bits.hold,
        update=update,
        on_step=checked,
    )
