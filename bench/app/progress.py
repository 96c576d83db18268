"""The progress of a sequence for the command line: points done of the total, the point under way
(frequency, amplitude, tyre pressure), elapsed time and an ETA.

On a terminal it is a live display of one line (rich, the display ``wfsbench index`` shows too:
:mod:`bench.app.live_display`) below the run log, whose lines are printed above it; while a prompt
waits for its answer it stands still, and at the sequence's end it is gone. In a pipe, a log file or
a dumb terminal it degrades to one plain line per point started, without control codes.

The figures (points, elapsed, ETA) are :class:`~bench.app.pace.SequencePace`'s, as on the terminal
UI's Run screen.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from types import TracebackType
from typing import TextIO

import numpy as np
from rich.progress import BarColumn

from bench.app.live_display import progress_display, redraws_in_place
from bench.app.pace import NOTHING_DONE, DoneBefore, SequencePace
from bench.engine import events as ev
from drivers.wfs_frame import Status
from sequences.runs import RunKind

#: Shortest interval (s, wall clock) between two redraws of the live display while samples come in.
REDRAW_PERIOD_S = 0.2
#: Characters of the live display's bar.
BAR_WIDTH = 10


def clock_text(seconds: float) -> str:
    """``h:mm:ss`` (or ``m:ss`` under an hour) of a duration; ``--:--`` when unknown."""
    if not math.isfinite(seconds) or seconds < 0:
        return "--:--"
    minutes, secs = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class _LiveStatus:
    """The status on a terminal: one line, a bar and the status text, below the lines printed.

    Drawn on request only (no refresh thread), so that what is drawn follows the events and a test
    sees it exactly; standard output and error are left as they are (the prompts' questions and
    answers, the interrupt handler's word go to the terminal directly)."""

    def __init__(self, stream: TextIO) -> None:
        self.display = progress_display(
            stream,
            BarColumn(bar_width=BAR_WIDTH),
            text="{task.description}",
            interactive=True,
            auto_refresh=False,
            redirect_stdout=False,
            redirect_stderr=False,
        )
        self.task = self.display.add_task("", total=1.0)

    @property
    def shown(self) -> bool:
        """The line is on the screen, redrawn as the figures change."""
        return self.display.live.is_started

    def show(self, done: float, text: str) -> None:
        """Draw the line (the bar ``done`` full, 0..1), starting the display if it is not shown."""
        self.display.update(self.task, completed=done, description=text)
        if self.shown:
            self.display.refresh()
        else:
            self.display.start()

    def print(self, text: str) -> None:
        """``text`` whole, as it is (no markup, no highlighting, no wrapping by rich), above the line."""
        self.display.console.out(text, highlight=False)

    def hold(self, done: float, text: str) -> None:
        """The line as a line of its own, no longer redrawn: what comes next (a question, its answer)
        starts below it and nothing draws over it until :meth:`show`."""
        self.display.update(self.task, completed=done, description=text)
        self.end()
        self.display.console.print(self.display)

    def end(self) -> None:
        """The line erased and the display stopped (the cursor shown again)."""
        self.display.stop()


class Progress:
    """Subscriber: the progress of a sequence on ``stream``; :meth:`line` writes a log line.

    ``live``: a live display on a terminal (default: when ``stream`` is a terminal that can redraw
    a line); ``clock``: the wall clock (seconds), injectable for tests; ``done_before``: what a
    resumed campaign file holds done already (the engine skips it): its points count as done, its
    estimated duration is not ahead. Use as a context manager, so that the live display ends
    whatever ends the sequence."""

    def __init__(
        self,
        stream: TextIO,
        *,
        live: bool | None = None,
        clock: Callable[[], float] = time.monotonic,
        done_before: DoneBefore = NOTHING_DONE,
    ) -> None:
        self.stream = stream
        self.clock = clock
        self.pace = SequencePace(clock=clock, done_before=done_before)
        self.point: str | None = None  # what is under way, for people
        self.at_amplitude: bool | None = None  # a dwell: tapering in (False), at amplitude (True)
        self._pressure_bar: float | None = None
        live = redraws_in_place(stream) if live is None else live
        self._display = _LiveStatus(stream) if live else None
        self._last_draw_s = -math.inf

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        if self._display is not None:
            self._display.end()

    @property
    def live(self) -> bool:
        """A live display on a terminal (else plain lines)."""
        return self._display is not None

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

    def _done(self) -> float:
        """The points done as a share of the total (0 for a sequence of none)."""
        pace = self.pace
        return pace.points_done / pace.total_points if pace.total_points else 0.0

    # -- output -----------------------------------------------------------------------------

    def line(self, text: str) -> None:
        """A log line: above the live display on a terminal, else as it is."""
        if self._display is not None:
            self._display.print(text)
        else:
            self.stream.write(text + "\n")
            self.stream.flush()

    def _draw(self) -> None:
        """The live display (if any) brought up to date, and shown if it was not."""
        if self._display is not None:
            self._display.show(self._done(), self.status())
            self._last_draw_s = self.clock()

    def _redraw(self) -> None:
        """The live display brought up to date if it is shown (not before the first point, nor while
        a prompt waits for its answer)."""
        if self._display is not None and self._display.shown:
            self._draw()

    def _show(self, point: str, at_amplitude: bool | None = None) -> None:
        """A new point (or a dwell's hold) under way: drawn live, or one plain line."""
        self.point, self.at_amplitude = point, at_amplitude
        if self._display is not None:
            self._draw()
        else:
            self.line(f"progress: {self.status()}")

    def _pressure_text(self) -> list[str]:
        return [] if self._pressure_bar is None else [f"{self._pressure_bar:g} bar"]

    def _run_text(self, event: ev.RunStarted) -> str:
        step = event.step
        if event.kind == RunKind.HAMMER:
            return "hammer blows"
        sweep = f"sweep {step.get('start_hz', math.nan):g}-{step.get('end_hz', math.nan):g} Hz"
        return ", ".join([sweep, f"{step.get('amplitude_mm', math.nan):g} mm", *self._pressure_text()])

    def _recorded(self, event: ev.SamplesRecorded) -> None:
        if self.at_amplitude is False and "status" in event.columns:
            hold = np.asarray(event.columns["status"]) & int(Status.AMPLITUDE_HOLD)
            if hold.any():  # the controller's hold output: the taper in is over
                self._show(self.point or "", at_amplitude=True)
                return
        if self.clock() - self._last_draw_s >= REDRAW_PERIOD_S:
            self._redraw()

    def _asked(self, event: ev.PromptAsked) -> None:
        """The bench waits for the operator: the status says so, on a line of its own (live: left on
        the screen and no longer redrawn, so that the question starts a line of its own and nothing
        draws over the answer being typed until it is given)."""
        self.point, self.at_amplitude = f"waiting for the operator: prompt {event.prompt_id}", None
        if self._display is not None:
            self._display.hold(self._done(), self.status())
        else:
            self.line(f"progress: {self.status()}")

    def _answered(self) -> None:
        """The operator answered: the live display comes back below the answer (without a point
        until the next one starts)."""
        self.point = None
        self._draw()

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
                self._answered()
            case ev.PointDone():
                self._redraw()
            case ev.SequenceFinished():
                self.point = None
                if self._display is not None:
                    self._display.end()
