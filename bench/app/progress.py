"""The progress of a sequence for the command line: points done of the total, the point under way
(frequency, amplitude, tyre pressure), elapsed time and an ETA.

On a terminal it is one status line redrawn in place, with the run log's lines written above it; in
a pipe or a log file it degrades to one plain line per point started, without control codes.

The figures (points, elapsed, ETA) are :class:`~bench.app.pace.SequencePace`'s, as on the terminal
UI's Run screen.
"""

from __future__ import annotations

import math
import shutil
import time
from collections.abc import Callable
from typing import TextIO

import numpy as np

from bench.app.pace import NOTHING_DONE, DoneBefore, SequencePace
from bench.engine import events as ev
from drivers.wfs_frame import Status

#: Shortest interval (s, wall clock) between two redraws of the live line.
REDRAW_PERIOD_S = 0.2
#: Characters of the live bar.
BAR_WIDTH = 10


def clock_text(seconds: float) -> str:
    """``h:mm:ss`` (or ``m:ss`` under an hour) of a duration; ``--:--`` when unknown."""
    if not math.isfinite(seconds) or seconds < 0:
        return "--:--"
    minutes, secs = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class Progress:
    """Subscriber: the progress of a sequence on ``stream``; :meth:`line` writes a log line.

    ``live``: redraw one line in place (default: when ``stream`` is a terminal); ``clock``: the wall
    clock (seconds), injectable for tests; ``done_before``: what a resumed campaign file holds done
    already (the engine skips it): its points count as done, its estimated duration is not ahead."""

    def __init__(
        self,
        stream: TextIO,
        *,
        live: bool | None = None,
        clock: Callable[[], float] = time.monotonic,
        done_before: DoneBefore = NOTHING_DONE,
    ) -> None:
        self.stream = stream
        self.live = stream.isatty() if live is None else live
        self.clock = clock
        self.pace = SequencePace(clock=clock, done_before=done_before)
        self.point: str | None = None  # what is under way, for people
        self.at_amplitude: bool | None = None  # a dwell: tapering in (False), at amplitude (True)
        self._pressure_bar: float | None = None
        self._shown = False  # a live line is on the screen
        self._asking = False  # a prompt waits for its answer: its question owns the terminal's line
        self._last_draw_s = -math.inf

    # -- figures ----------------------------------------------------------------------------

    @property
    def elapsed_s(self) -> float:
        return self.pace.elapsed_s

    @property
    def eta_s(self) -> float:
        return self.pace.eta_s

    def status(self) -> str:
        """The status line: points done of total, the point under way, elapsed and ETA."""
        pace = self.pace
        parts = [
            f"{pace.points_done}/{pace.total_points} points",
            f"elapsed {clock_text(self.elapsed_s)}, ETA {clock_text(self.eta_s)}",
        ]
        if self.point is not None:  # last: a narrow terminal cuts the line's end
            phase = {None: "", False: ", tapering in", True: ", at amplitude"}[self.at_amplitude]
            parts.append(self.point + phase)
        return " | ".join(parts)

    # -- output -----------------------------------------------------------------------------

    def line(self, text: str) -> None:
        """A log line: above the live line on a terminal, else as it is."""
        if self.live and self._shown:
            self.stream.write("\r\x1b[K")
            self._shown = False
        self.stream.write(text + "\n")
        if self.live and self.point is not None and not self._asking:
            self._draw()
        self.stream.flush()

    def _draw(self) -> None:
        pace = self.pace
        done = pace.points_done / pace.total_points if pace.total_points else 0.0
        filled = min(BAR_WIDTH, round(done * BAR_WIDTH))
        text = f"[{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {self.status()}"
        width = shutil.get_terminal_size().columns
        self.stream.write("\r" + text[: max(width - 1, 10)] + "\x1b[K")
        self.stream.flush()
        self._shown = True
        self._last_draw_s = self.clock()

    def _show(self, point: str, at_amplitude: bool | None = None) -> None:
        """A new point (or a dwell's hold) under way: redrawn live, or one plain line."""
        self.point, self.at_amplitude = point, at_amplitude
        if self.live:
            self._draw()
        else:
            self.line(f"progress: {self.status()}")

    def _pressure_text(self) -> list[str]:
        return [] if self._pressure_bar is None else [f"{self._pressure_bar:g} bar"]

    def _run_text(self, event: ev.RunStarted) -> str:
        step = event.step
        if event.kind == "hammer":
            return "hammer blows"
        sweep = f"sweep {step.get('start_hz', math.nan):g}-{step.get('end_hz', math.nan):g} Hz"
        return ", ".join([sweep, f"{step.get('amplitude_mm', math.nan):g} mm", *self._pressure_text()])

    def _recorded(self, event: ev.SamplesRecorded) -> None:
        if self.at_amplitude is False and "status" in event.columns:
            hold = np.asarray(event.columns["status"]) & int(Status.AMPLITUDE_HOLD)
            if hold.any():  # the controller's hold output: the taper in is over
                self._show(self.point or "", at_amplitude=True)
                return
        due = self.clock() - self._last_draw_s >= REDRAW_PERIOD_S
        if self.live and self.point is not None and due and not self._asking:
            self._draw()

    def _asked(self, event: ev.PromptAsked) -> None:
        """The bench waits for the operator: the status says so, on a line of its own (live: ended
        with a newline, so that the question starts a line of its own and no redraw overwrites the
        answer being typed until it is given)."""
        self.point, self.at_amplitude = f"waiting for the operator: prompt {event.prompt_id}", None
        if self.live:
            self._draw()
            self.stream.write("\n")
            self.stream.flush()
            self._shown, self._asking = False, True
        else:
            self.line(f"progress: {self.status()}")

    def __call__(self, event: ev.Event) -> None:
        self.pace(event)
        match event:
            case ev.RunStarted():
                self._pressure_bar = event.conditions.get("tyre_pressure_bar")
                if event.kind in ("sweep", "hammer"):  # one point, published at its end only
                    self._show(f"{event.run_id}: {self._run_text(event)}")
            case ev.SamplesRecorded():
                self._recorded(event)
            case ev.PointStarted():
                what = [f"{event.freq_hz:g} Hz", f"{event.amplitude_mm:.3g} mm", *self._pressure_text()]
                self._show(f"{event.run_id} point {event.index}: {', '.join(what)}", at_amplitude=False)
            case ev.PromptAsked():
                self._asked(event)
            case ev.PromptAnswered():
                self._asking = False
            case ev.PointDone():
                if self.live and not self._asking:
                    self._draw()
            case ev.SequenceFinished():
                self.point, self._asking = None, False
                if self.live and self._shown:
                    self.stream.write("\r\x1b[K")
                    self._shown = False
                    self.stream.flush()
