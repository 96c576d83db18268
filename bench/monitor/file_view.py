"""The monitor's state read from a campaign file, being recorded or finished
(``wfsbench monitor FILE``).

A file a run is writing is read without its lock (:func:`~bench.store.open_campaign` with
``while_written``): what the writer has flushed, read again every :data:`POLL_S`; a read that meets a
flush under way keeps the state read before and tries again. The state has the layout of the live
monitor's (docs/monitor.md) with ``source`` "file": the runs and their status, the points done, the
last analysis of each run with its flags, the events as stored, the interlocks that tripped and the
last run's link counters; no live values (the file holds no "now").
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench import locks
from bench.app.analysis_record import parse_record
from bench.app.bench_status import interlock_lamps, state_tone
from bench.config import parse_bench_config
from bench.monitor.view import EVENTS_KEPT, STATE_FORMAT, analysis_entry
from bench.store import StoreError, open_campaign
from bench.store.schema import campaign_key
from bench.store.typed import TypedFormatError
from sequences import parse_sequence
from sequences.points import PointStatus
from sequences.runs import EventKind

#: How often the file is read again (s).
POLL_S = 1.0
#: The state shown while the file is being recorded, and once it is not.
RECORDING, FINISHED = "recording", "finished"


def planned_points(config_toml: str, sequence_toml: str) -> int | None:
    """The points of the file's first sequence, as the engine counts them; None when the stored
    sequence cannot be read back."""
    try:
        config = parse_bench_config(config_toml, "<stored configuration>")
        return parse_sequence(sequence_toml, "<stored sequence>", config.limits, config.channels).points()
    except Exception:  # a file of another source (an import) may hold no runnable sequence
        return None


def file_state(path: Path) -> dict[str, Any]:
    """The state of the campaign file at ``path`` (StoreError when it cannot be read now)."""
    holder = locks.holder_of(campaign_key(path))
    state = RECORDING if holder is not None else FINISHED
    with open_campaign(path, while_written=holder is not None) as campaign:
        runs, analyses, lines, tripped = [], [], [], {}
        done = 0
        for event in campaign.events:
            lines.append(f"{event.kind}: {event.text}")
        for run in campaign.runs:
            runs.append({"run_id": run.run_id, "kind": run.kind, "status": run.status, "reason": run.reason})
            done += sum(1 for p in run.points if p.status == PointStatus.DONE)
            why = f": {run.reason}" if run.reason else ""
            lines.append(f"run {run.run_id} ({run.kind}): {run.status}{why}")
            for event in run.events:
                lines.append(f"  {event.kind}: {event.text}")
                if event.kind == EventKind.INTERLOCK:
                    tripped[str(event.fields.get("name", event.text))] = str(event.fields.get("reason", ""))
            record = run.analysis_record
            if record is not None:
                analyses.append(_analysis(run.run_id, record))
        last = campaign.runs[-1] if campaign.runs else None
        planned = planned_points(campaign.config_toml, campaign.sequence_toml)
        return {
            "format": STATE_FORMAT,
            "source": "file",
            "bench": f"campaign file {path}",
            "state": state,
            "tone": state_tone(state).value,
            "recorder": str(holder) if holder is not None else None,
            "sequence": {"name": campaign.sequence_name, "status": state, "reason": ""},
            "run": last.run_id if last else None,
            "step": f"run {last.run_id} ({last.kind}): {last.status}" if last else None,
            "prompt": None,
            "points_done": done,
            "points_planned": planned,
            "points_done_before": 0,
            "elapsed_s": None,
            "eta_s": None,
            "awaiting_operator": False,
            "live": None,
            "lamps": [{"text": lamp.text, "ok": lamp.ok} for lamp in interlock_lamps((), tripped)],
            "counters": dict(last.link_counters) if last else {},
            "runs": runs,
            "analyses": analyses,
            "events": [{"n": n, "text": text} for n, text in enumerate(lines, 1)][-EVENTS_KEPT:],
            "events_total": len(lines),
        }


def _analysis(run_id: str, record: str) -> dict[str, Any]:
    """A run's stored analysis as the state lists it (a record this software cannot read: said)."""
    try:
        return analysis_entry(parse_record(record).outcome)
    except TypedFormatError as exc:
        why = f"its record cannot be read: {exc}"
        return {
            "run_id": run_id,
            "analysis": "",
            "status": "unreadable",
            "why": why,
            "flags": [],
            "summary": [],
        }


class FileWatch:
    """Reads the campaign file at ``path`` every :data:`POLL_S` on a thread of its own and calls
    ``publish`` with its state whenever it changed (``error`` says why a read failed, the state
    before kept)."""

    def __init__(self, path: Path, publish: Callable[[dict[str, Any]], object]) -> None:
        self.path = path
        self._publish = publish
        self._stop = threading.Event()
        self._last: dict[str, Any] | None = None
        self.error: str | None = None
        self.reads = 0
        self._thread = threading.Thread(target=self._run, name="monitor-file", daemon=True)

    def start(self) -> None:
        """Read the file once here (StoreError when it is no campaign file), then keep watching."""
        self._take(file_state(self.path))
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        while not self._stop.wait(POLL_S):
            try:
                state = file_state(self.path)
            except (StoreError, OSError) as exc:  # a flush under way, or the file replaced: next time
                self.error = str(exc)
                continue
            self.error = None
            self._take(state)

    def _take(self, state: dict[str, Any]) -> None:
        self.reads += 1
        if state != self._last:
            self._last = state
            self._publish(state)
