"""The four screens of the UI as panes of one switcher: bench, sequence, run, results.

Each pane only shows what it is given (``show_*`` methods called on the UI's thread); the app
routes the session's messages to them and owns the keys."""

from __future__ import annotations

import math

import numpy as np
from rich.markup import escape
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import DataTable, Input, Label, OptionList, Static

from bench.app.analysis_plan import analysis_limits
from bench.app.bench_status import interlock_lamps, point_text
from bench.app.check import step_line
from bench.app.durations import sequence_estimate_text
from bench.app.live_trace import LiveTrace
from bench.app.pace import SequencePace
from bench.app.plan import CampaignPlan
from bench.engine import events as ev
from bench.tui.plot import BraillePlot, Series
from bench.tui.session import BodeCurves, ControllerStatus, PastRun, SequenceLaunched
from sequences import shipped_files

#: Shipped sequence files offered on the sequence screen.
#: The shipped sequences as listed, the seconds-long smoke check first.
SHIPPED = tuple(sorted(shipped_files(), key=lambda name: name != "smoke.toml"))


#: Samples younger than this (s) are shown as live; older ones with their age.
LIVE_AGE_S = 2.0
#: What the live line says without samples, and after the values it shows from a past run.
IDLE_NOTE = "the WFS streams during runs only"


def show_text(widget: Static, text: str) -> None:
    """Give ``widget`` the text ``text``, leaving it alone when it shows that already: an update
    lays the screen out again, and the live lines are refreshed ten times a second, in the process
    that reads the WFS."""
    if widget.content != text:
        widget.update(text)


def metadata_text(given: dict[str, str]) -> str:
    """The operator and notes typed in (m), as the Sequence screen shows them."""
    if not given:
        return "operator, notes: not given ([b]m[/b]: enter them; the files' \\[metadata] apply)"
    shown = "; ".join(f"{name}: {escape(value)}" for name, value in given.items())
    return f"{shown}  ([b]m[/b]: change)"


def age_text(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"


def live_text(trace: LiveTrace | None, running: bool) -> str:
    """The live values line: live during a run, else the last values marked with their age and
    the run that recorded them (the WFS streams during runs only), or that there are none."""
    values = trace.latest() if trace is not None else {}
    if not values:
        return f"[b]live[/b]  no live values while idle: {IDLE_NOTE}"
    v = values
    figures = (
        f"Fz {v['fz_wfs_n']:9.1f} N   plate force {v['f_plate_n']:9.1f} N   "
        f"displacement {v['z_base_m'] * 1e3:7.3f} mm   hub acc. {v['a_hub_m_s2']:7.2f} m/s²"
    )
    age = trace.age_s()
    if running and age is not None and age < LIVE_AGE_S:
        return f"[b]live[/b]  {figures}"
    during = f", during {trace.last_run}" if trace.last_run else ""
    return (
        f"[b]last seen[/b] [yellow]{age_text(age or 0.0)} ago{during}[/yellow] ({IDLE_NOTE})\n"
        f"      [dim]{figures}[/dim]"
    )


def lamp(ok: bool | None, text: str) -> str:
    colour = "green" if ok else "grey50" if ok is None else "red"
    return f"[{colour}]●[/{colour}] {text}"


class BenchPane(Vertical):
    """Links, hydraulic state, interlock lamps, live values and link counters."""

    def compose(self) -> ComposeResult:
        yield Static("opening the bench…", id="bench-links")
        yield Static("", id="bench-lamps")
        yield Static("", id="bench-values")
        yield Static("", id="bench-counters")
        yield Label("l / h / o: hydraulics low / high / off   t: tare   x: reset   (each asks y / n)")

    def show_opening(self) -> None:
        self.query_one("#bench-links", Static).update("opening the bench…")

    def show_unopened(self, reason: str) -> None:
        self.query_one("#bench-links", Static).update(
            f"[b red]the bench did not open[/b red]: {reason}\n"
            "[b]b[/b]: open it again (once the cause is fixed)"
        )

    def show(
        self,
        *,
        bench: str,
        engine_state: str,
        controller: ControllerStatus | None,
        actuator_fault: str | None,
        wfs_connected: bool | None,
        tripped: dict[str, str],
        failure: str | None,
        interlocks: tuple[str, ...],
        trace: LiveTrace | None,
        running: bool,
        counters: dict[str, int],
    ) -> None:
        """``interlocks``: a lamp each, every interlock the engine can trip, red while ``tripped``
        (name: reason) holds it; a tripped name without a lamp of its own gets a red one, so a run
        that ended interlocked never leaves every lamp green. The controller's own interlock and a
        failed sequence show as red lamps of their own."""
        state = controller.state if controller else "not read yet"
        show_text(
            self.query_one("#bench-links", Static),
            f"[b]{bench}[/b]   state [b]{engine_state}[/b]   controller {state}\n"
            + lamp(actuator_fault is None, f"controller link {actuator_fault or 'up'}")
            + "    "
            + lamp(wfs_connected, "WFS link " + ("up" if wfs_connected else "down")),
        )
        lamps = [
            lamp(shown.ok, shown.text)
            for shown in interlock_lamps(
                interlocks,
                tripped,
                controller_state=controller.state if controller else None,
                controller_interlock=controller.interlock if controller else None,
                failure=failure,
            )
        ]
        show_text(self.query_one("#bench-lamps", Static), "[b]interlocks[/b]  " + "   ".join(lamps))
        show_text(self.query_one("#bench-values", Static), live_text(trace, running))
        show_text(
            self.query_one("#bench-counters", Static),
            "[b]WFS link[/b]  "
            + "   ".join(f"{name.replace('_', ' ')} {value}" for name, value in counters.items()),
        )


class SequencePane(Vertical):
    """Pick a shipped sequence or type a path; the check's lines or its refusal."""

    def compose(self) -> ComposeResult:
        yield Label("shipped sequences (Enter checks one), or a sequence file's path:")
        yield OptionList(*SHIPPED, id="seq-shipped")
        yield Input(placeholder="path/to/sequence.toml, then Enter", id="seq-path")
        yield Static(metadata_text({}), id="seq-metadata")
        with VerticalScroll(id="seq-report-box"):
            yield Static("no sequence checked yet", id="seq-report")

    def show_metadata(self, given: dict[str, str]) -> None:
        """The operator and notes typed in for the runs to come."""
        self.query_one("#seq-metadata", Static).update(metadata_text(given))

    def show_checking(self, path: str) -> None:
        self.query_one("#seq-report", Static).update(f"checking {path}…")

    def show_plan(self, plan: CampaignPlan) -> None:
        s = plan.sequence
        # what to do next comes first: a long sequence's steps run below the pane's visible rows
        lines = [
            f"[b]{s.name}[/b] ({s.source}) on the {plan.config.kind} bench: [green]valid[/green]",
            sequence_estimate_text(s),
            "[b]g[/b]: start this sequence",
        ]
        limits = analysis_limits(s, plan.config)  # what ``wfsbench check`` says of the analysis
        if limits:
            lines.append(
                f"[b yellow]analysis limited ({len(limits)})[/b yellow]:"
                " what the runs will not let the analysis give:"
            )
            lines += [f"  - {escape(limit)}" for limit in limits]
        else:
            lines.append("analysis: every run can be analysed in full")
        lines += [f"  {escape(step_line(i, step))}" for i, step in enumerate(s.steps)]
        self.query_one("#seq-report", Static).update("\n".join(lines))

    def show_error(self, path: str, error: str) -> None:
        self.query_one("#seq-report", Static).update(
            f"[b red]{path}: cannot run[/b red] (nothing starts until it is valid)\n{error}"
        )


class RunPane(Vertical):
    """Progress, the current step, live plots and commanded against achieved amplitudes."""

    def compose(self) -> ComposeResult:
        yield Static("no sequence running", id="run-progress")
        yield Static("", id="run-step")
        with Horizontal(id="run-plots"):
            yield BraillePlot("forces", "N", id="plot-force")
            yield BraillePlot("displacement", "mm", id="plot-disp")
        yield DataTable(id="run-points", cursor_type="none", zebra_stripes=True)
        yield Label("p: pause    r: resume    a: abort")

    def on_mount(self) -> None:
        table = self.query_one("#run-points", DataTable)
        table.add_columns(
            "run", "point", "f Hz", "status", "target mm", "commanded mm", "achieved mm", "added because"
        )
        self._launched: SequenceLaunched | None = None
        self._ended: str | None = None  # what the sequence shown ended as (None: under way, or none)

    def launched(self, launched: SequenceLaunched) -> None:
        """A sequence goes to the engine; a resume's points done already count from its start."""
        self._launched = launched

    def sequence_started(self, event: ev.SequenceStarted) -> None:
        launched = self._launched
        self._ended = None
        self.query_one("#run-points", DataTable).clear()
        resumed = " (resumed)" if launched is not None and launched.resume else ""
        self.query_one("#run-step", Static).update(f"sequence {event.sequence_name}{resumed}")

    def sequence_finished(self, event: ev.SequenceFinished) -> None:
        """Nothing is under way any more: the point line and the plots say so instead of showing the
        last dwell as if it ran."""
        self._ended = event.status
        name = self._launched.name if self._launched is not None else "the sequence"
        why = f": {event.reason}" if event.reason else ""
        self.query_one("#run-step", Static).update(f"{name} {event.status}{why}; no point under way")
        for plot_id in ("#plot-force", "#plot-disp"):
            self.query_one(plot_id, BraillePlot).plot([], "no sequence running")

    def point_started(self, event: ev.PointStarted) -> None:
        self.query_one("#run-step", Static).update(f"[b]{event.run_id}[/b]  {point_text(event)}")

    def grid_refined(self, event: ev.GridRefined) -> str:
        """What to tell the technician of the points an adaptive grid adds."""
        added = "; ".join(f"{freq_hz:g} Hz ({reason})" for freq_hz, reason in event.added)
        return f"{event.run_id}: point added at {event.amplitude_mm:g} mm: {added}"

    def point_done(self, event: ev.PointDone) -> None:
        achieved = f"{event.achieved_amplitude_mm:.3f}" if math.isfinite(event.achieved_amplitude_mm) else "-"
        table = self.query_one("#run-points", DataTable)
        table.add_row(
            event.run_id.rsplit("-", 2)[-2],
            str(event.index),
            f"{event.freq_hz:g}",
            event.status,
            f"{event.amplitude_mm:.3f}",
            f"{event.commanded_amplitude_mm:.3f}",
            achieved,
            event.added_reason,
        )
        table.scroll_end(animate=False)

    def show_progress(self, state: str, pace: SequencePace | None) -> None:
        """The state, points done of the total, elapsed and ETA (:class:`SequencePace`'s figures:
        the ETA holds still while the operator is awaited); both clocks stop when the sequence ends."""
        if pace is None or not pace.started:
            text = f"state [b]{state}[/b]; no sequence started"
        else:
            before = pace.done_before.points
            eta_s = pace.eta_s
            eta = f"ETA {eta_s:5.0f} s" if math.isfinite(eta_s) else "ETA --"
            if pace.ended:
                eta = self._ended or "ended"
            elif pace.awaiting_operator:
                eta += " (waiting for the operator)"
            resumed = f" ({before} done before the resume)" if before else ""
            text = (
                f"state [b]{state}[/b]   points {pace.points_done}/{pace.total_points}{resumed}"
                f"   elapsed {pace.elapsed_s:5.0f} s   {eta}"
            )
        show_text(self.query_one("#run-progress", Static), text)

    def show_trace(self, trace: LiveTrace) -> None:
        if self._ended is not None:  # the plots were cleared at the end: no dwell is under way
            return
        t_s, v = trace.snapshot()
        if not t_s.size:
            return
        note = f"last {-t_s[0]:.1f} s"
        self.query_one("#plot-force", BraillePlot).plot(
            [
                Series("Fz WFS", t_s, v["fz_wfs_n"], "cyan"),
                Series("plate force", t_s, v["f_plate_n"], "yellow"),
            ],
            note,
        )
        self.query_one("#plot-disp", BraillePlot).plot([Series("z", t_s, v["z_base_m"] * 1e3, "green")], note)


class ResultsPane(Vertical):
    """The analysis of each run, the Bode plot of the force ratio, the runs of the open file.

    Only the analysis text scrolls (it grows with every run and with whatever a run flags): the
    Bode plot, the valid bands and the runs table stay in view below it at any length of text."""

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="results-text"):
            yield Static("no results yet", id="results-lines")
        with Horizontal(id="results-bode"):
            yield BraillePlot("|F_wfs/F_contact|", "|H|", id="bode-mag")
            yield BraillePlot("phase", "deg", id="bode-phase")
        yield Static("", id="results-bands")
        yield Label("[b]runs of the open file[/b]")
        yield DataTable(id="results-runs", cursor_type="none", zebra_stripes=True)

    def on_mount(self) -> None:
        self.query_one("#results-runs", DataTable).add_columns("run", "kind", "status", "samples", "reason")
        self._lines: list[str] = []

    def clear_results(self) -> None:
        self._lines = []
        self.query_one("#results-lines", Static).update("no results yet")

    def add_result(self, run_id: str, lines: tuple[str, ...], bode: tuple[BodeCurves, ...]) -> None:
        self._lines += [f"[b]{run_id}[/b]", *(f"  {line}" for line in lines)]
        self.query_one("#results-lines", Static).update("\n".join(self._lines))
        if bode:
            self._show_bode(bode)

    def _show_bode(self, bode: tuple[BodeCurves, ...]) -> None:
        mag, phase, bands = [], [], []
        styles = (("cyan", "magenta"), ("yellow", "green"))
        for i, curves in enumerate(bode):
            raw_style, comp_style = styles[i % len(styles)]
            x = np.log10(curves.freq_hz)
            mag += [
                Series(f"raw {curves.label}", x, np.abs(curves.raw), raw_style),
                Series(f"compensated {curves.label}", x, np.abs(curves.compensated), comp_style),
            ]
            phase += [
                Series(f"raw {curves.label}", x, np.degrees(np.angle(curves.raw)), raw_style),
                Series(
                    f"compensated {curves.label}", x, np.degrees(np.angle(curves.compensated)), comp_style
                ),
            ]
            bands += [f"valid band {curves.label} {band}" for band in curves.bands]
        f = bode[0].freq_hz
        note = f"log frequency {f.min():g}-{f.max():g} Hz"
        self.query_one("#bode-mag", BraillePlot).plot(mag, note)
        self.query_one("#bode-phase", BraillePlot).plot(phase, note)
        self.query_one("#results-bands", Static).update("\n".join(bands))

    def show_runs(self, runs: tuple[PastRun, ...]) -> None:
        table = self.query_one("#results-runs", DataTable)
        table.clear()
        for r in runs:
            table.add_row(r.run_id, r.kind, r.status, str(r.n_samples), r.reason or "")
