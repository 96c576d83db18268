"""Amplitude control: the achieved displacement amplitude against the commanded one.

A servo-hydraulic actuator does not reach the commanded amplitude exactly: the oil column, the valve
and the specimen's load change its gain with frequency. After each dwell the engine measures the
achieved amplitude on the displacement channel; beyond the tolerance the command is scaled by the
ratio of target to achieved (the inverse of the gain just measured at this very point) and the point
is repeated, a bounded number of times. Commanded, corrected and achieved amplitudes are recorded.

Three rules keep a command from being changed on what the bench did not see, or by too much:

- **Frames present** (:class:`FramesPresent`): a measurement is fitted on the samples' true times
  (:mod:`bench.numerics.sine_fit`) and a decision is taken only on a window that holds enough whole
  cycles of frames and misses no more than a stated fraction of them. A window short of that is
  measured again at the same command: it never scales the command.
- **Bounded steps**: one correction scales the command by at most ``max_step_factor`` (a lab's
  controller allows 10-20 % a step).
- **Bounded commands** (:meth:`AmplitudeControl.command_cap_mm`): the command for a target never
  exceeds what the dry run's bench model commands for it (the target itself: the model's plate
  follows its command) by more than ``command_margin``, nor the soft limits' largest; a correction
  beyond that ends the point flagged, not driven.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.numerics.sine_fit import SineFit
from sequences.response_limits import LimitAction

#: The limit a measured amplitude beyond its target reaches (:meth:`AmplitudeControl.excursion`).
AMPLITUDE_EXCURSION = "amplitude excursion"


@dataclass(frozen=True)
class FramesPresent:
    """When a window holds enough of the bench's frames for a control decision: at least
    ``min_cycles`` whole cycles' worth of frames present, and at most ``max_missing_fraction`` of
    its sample times without a frame (the bench configuration's ``[amplitude]``)."""

    max_missing_fraction: float = 0.05
    min_cycles: float = 1.0

    def refusal(self, fit: SineFit | None) -> str:
        """Why no decision may be taken on ``fit``'s window (empty: it may)."""
        if fit is None:
            return "holds no whole cycle"
        return self.refusal_of(fit.frames_present, fit.span_samples, fit.freq_hz, fit.sample_rate_hz)

    def refusal_of(
        self, frames_present: int, span_samples: int, freq_hz: float, sample_rate_hz: float
    ) -> str:
        """Why no decision may be taken on a window of ``span_samples`` sample times holding
        ``frames_present`` frames of a sine at ``freq_hz`` (empty: it may)."""
        if span_samples <= 0:
            return "holds no whole cycle"
        missing = span_samples - frames_present
        if missing > self.max_missing_fraction * span_samples:
            return (
                f"missed {missing} of its {span_samples} frames ({100 * missing / span_samples:.1f} %;"
                f" at most {100 * self.max_missing_fraction:g} % allowed)"
            )
        cycles = frames_present * freq_hz / sample_rate_hz
        if cycles < self.min_cycles - 1e-9:
            return f"holds {cycles:.2f} cycles of frames (at least {self.min_cycles:g})"
        return ""


@dataclass(frozen=True)
class AmplitudeDecision:
    """``keep``: the point stands; otherwise repeat it with ``corrected_mm``. ``note`` says why."""

    keep: bool
    corrected_mm: float | None
    error: float  # (achieved - target) / target
    note: str = ""


@dataclass(frozen=True)
class AmplitudeControl:
    """``tolerance``: relative amplitude error accepted; ``max_corrections``: repeats per point;
    ``max_command_mm``: the largest command the soft limits allow; ``max_step_factor``: the most
    one correction scales the command by; ``command_margin``: how far (a fraction) a command may
    exceed its target; ``excursion_tolerance``: how far (a fraction) a measured amplitude may
    exceed its target before the limit :data:`AMPLITUDE_EXCURSION` is reached, acted on with
    ``excursion_action``."""

    tolerance: float = 0.02
    max_corrections: int = 3
    max_command_mm: float = float("inf")
    max_step_factor: float = 1.15
    command_margin: float = 0.25
    excursion_tolerance: float = 0.1
    excursion_action: LimitAction = LimitAction.INDICATE

    def excursion(self, target_mm: float, achieved_mm: float) -> str:
        """Why ``achieved_mm`` is an excursion beyond ``target_mm`` (empty: it is none)."""
        if np.isfinite(achieved_mm) and achieved_mm > target_mm * (1 + self.excursion_tolerance):
            return (
                f"the plate's amplitude {achieved_mm:.3f} mm exceeds the {target_mm:g} mm target by"
                f" {100 * (achieved_mm / target_mm - 1):.0f} % (at most {100 * self.excursion_tolerance:g} %)"
            )
        return ""

    def command_cap_mm(self, target_mm: float) -> float:
        """The largest command allowed for ``target_mm``."""
        return min(self.max_command_mm, target_mm * (1 + self.command_margin))

    def servo_gains(self) -> ServoGains:
        """Fresh gains for one run, each start command within the command margin of its target."""
        return ServoGains(1 + self.command_margin)

    def step(self, target_mm: float, achieved_mm: float) -> float:
        """The factor a correction scales the command by, within the step bound."""
        bound = self.max_step_factor
        return float(np.clip(target_mm / achieved_mm, 1 / bound, bound))

    def cap_refusal(self, target_mm: float, command_mm: float, *, called: str = "the command") -> str:
        """Why ``command_mm`` may not be sent for ``target_mm`` (empty: it may); ``called``: how the
        reason names the command ("the update to")."""
        if command_mm > self.max_command_mm:
            return f"{called} {command_mm:.3f} mm exceeds the {self.max_command_mm:g} mm limit"
        if command_mm > target_mm * (1 + self.command_margin):
            return (
                f"{called} {command_mm:.3f} mm exceeds the bench model's {target_mm:g} mm for the"
                f" target by more than {100 * self.command_margin:g} %"
            )
        return ""

    def decide(
        self,
        target_mm: float,
        commanded_mm: float,
        achieved_mm: float,
        corrections: int,
        *,
        refusal: str = "",
    ) -> AmplitudeDecision:
        """What follows an attempt that achieved ``achieved_mm`` under ``commanded_mm``; ``refusal``:
        why its measurement may not be decided on (frames missing): the point is measured again at
        the same command, as a correction would be counted, and kept flagged once none is left."""
        error = (achieved_mm - target_mm) / target_mm
        if refusal:
            return self._measure_again(commanded_mm, error, corrections, refusal)
        if abs(error) <= self.tolerance:
            return AmplitudeDecision(True, None, error)
        if kept := self._kept_off_target(error, achieved_mm, corrections):
            return AmplitudeDecision(True, None, error, kept)
        corrected = commanded_mm * self.step(target_mm, achieved_mm)
        if cap := self.cap_refusal(target_mm, corrected):
            return AmplitudeDecision(
                True, None, error, f"amplitude {100 * error:+.1f} %: not corrected, {cap}"
            )
        return AmplitudeDecision(False, corrected, error)

    def _kept_off_target(self, error: float, achieved_mm: float, corrections: int) -> str:
        """Why a point off its target is kept as it is (empty: it is corrected)."""
        if not np.isfinite(achieved_mm) or achieved_mm <= 0:
            return "no displacement measured: amplitude not corrected"
        if corrections >= self.max_corrections:
            return f"amplitude {100 * error:+.1f} % after {corrections} corrections"
        return ""

    def _measure_again(
        self, commanded_mm: float, error: float, corrections: int, refusal: str
    ) -> AmplitudeDecision:
        """An attempt whose measurement may not be decided on: the same command again, counted as
        a correction; kept flagged once none is left."""
        if corrections >= self.max_corrections:
            return AmplitudeDecision(True, None, error, f"amplitude not verified: {refusal}")
        return AmplitudeDecision(False, commanded_mm, error, f"measured again at the same command: {refusal}")


def amplitude_mm(fit: SineFit | None) -> float:
    """A fit's amplitude in mm (NaN: none)."""
    return float("nan") if fit is None else 1e3 * fit.amplitude


class ServoGains:
    """The actuator's gain (achieved over commanded amplitude) measured last at each frequency, to
    start a new point with the command that reaches its target: the gain changes slowly with
    frequency (and amplitude), so the gain interpolated from the points already run (the nearest
    one's beyond them) saves most repeats when an adaptive grid adds points between its
    frequencies or runs its next amplitude. Only gains measured on windows with their frames
    present are recorded."""

    def __init__(self, max_factor: float = 1.25) -> None:
        """``max_factor``: the most a start command may differ from its target (either way)."""
        self.max_factor = max_factor
        self._gain: dict[float, float] = {}

    def record(self, freq_hz: float, commanded_mm: float, achieved_mm: float) -> None:
        if np.isfinite(achieved_mm) and achieved_mm > 0 and commanded_mm > 0:
            self._gain[freq_hz] = achieved_mm / commanded_mm

    def command_mm(self, freq_hz: float, target_mm: float) -> float:
        """The command expected to achieve ``target_mm`` at ``freq_hz`` (the target when no gain is
        known yet), never differing from the target by more than :attr:`max_factor`."""
        if not self._gain:
            return target_mm
        freqs = sorted(self._gain)
        gain = float(np.interp(freq_hz, freqs, [self._gain[f] for f in freqs]))
        return target_mm * float(np.clip(1.0 / gain, 1 / self.max_factor, self.max_factor))
