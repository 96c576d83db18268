"""Write a campaign file incrementally: one run at a time, blocks of samples as they arrive.

Durability is flush-based (why not SWMR, and why this is safe: ``docs/hdf5.md``). A channel's
chunk holds one flush interval of samples. Sample blocks are kept in memory, one buffer per
channel, until a flush, which writes the whole chunks they fill (each compressed here, as the
channel's filters would, and handed to HDF5 finished), the point rows whose samples are now
written, then flushes the whole file (HDF5 flush: what a killed writer leaves is this state).
A chunk is written once and never rewritten, so a writer killed in the middle of a flush cannot
damage what an earlier flush made durable; the last, partial chunk is written when the run ends.
Every write checks the cadence and flushes once a chunk is full or
:data:`~bench.store.schema.FLUSH_INTERVAL_S` of wall time has passed since the last ``fsync``,
so less than one flush interval of samples is ever at risk from a killed writer. The file is
``fsync`` ed with a flush once that interval of wall time has passed since the last ``fsync``,
and with every explicit :meth:`CampaignWriter.flush`, run end and close: a power loss can take
in addition what was flushed in the last interval of wall time (about one interval of samples
at the real-time rate; a simulated bench running faster flushes many chunks per ``fsync``).
A run is created with status ``"incomplete"`` and keeps it until :meth:`RunWriter.finish`, so a
run whose writer died reads as incomplete.

Resume (``docs/hdf5.md``): :meth:`CampaignWriter.open_append` reopens a file;
:meth:`CampaignWriter.continue_run` goes on writing an incomplete run where its durable data ends,
or :meth:`CampaignWriter.begin_run` with ``resumes=`` starts a new run that takes over the points
the old one had not done. Either way a point can be marked done once only.
"""

from __future__ import annotations

import hashlib
import os
import time
import zlib
from collections.abc import Callable, Mapping, Sequence
from datetime import UTC, datetime
from functools import cache
from itertools import pairwise
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from h5py import h5s, h5t, h5z

from bench import locks
from bench.store import schema as s
from bench.store.reader import open_campaign, readable_length
from bench.store.results import as_mapping, write_tree
from bench.store.schema import StoreError
from sequences.channels import Channel
from sequences.metadata import merged, metadata_value, specimen_conflicts
from sequences.points import PointAttempt, PointStatus
from sequences.runs import FINISH_STATUSES, RUN_KINDS, EventKind, RunStatus

_DTYPE_LIMITS = {"u4": (0, 2**32 - 1), "u2": (0, 2**16 - 1)}


def _now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


class CampaignWriter:
    """The writing side of one campaign file; one run is written at a time.

    Use :meth:`create` for a new file and :meth:`open_append` to resume one; close with
    :meth:`close` (or a ``with`` block), which finishes nothing: an unfinished run stays incomplete.
    """

    def __init__(
        self,
        file: h5py.File,
        path: Path,
        *,
        flush_interval_s: float,
        clock: Callable[[], float],
        metadata: Mapping[str, str] | None = None,
    ) -> None:
        self._file = file
        self.path = path
        #: the test metadata this session states (every field; empty: not stated): its runs record
        #: their own fields of it (:data:`~bench.store.schema.RUN_METADATA_FIELDS`)
        self.metadata = merged(metadata or {})
        self.flush_interval_s = flush_interval_s
        self._run: RunWriter | None = None
        self._clock = clock
        self._last_sync_wall_s = clock()

    @classmethod
    def create(
        cls,
        path: str | Path,
        *,
        software_version: str,
        config_toml: str,
        sequence_toml: str,
        sequence_name: str,
        config_name: str = "",
        metadata: Mapping[str, str] | None = None,
        flush_interval_s: float = s.FLUSH_INTERVAL_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> CampaignWriter:
        """A new campaign file at ``path`` (refused if one exists: a campaign is never overwritten)
        holding what produced it: the software version, the bench configuration and the sequence as
        TOML text with their names (file names, or a description when they came from elsewhere),
        and the test ``metadata`` (field -> text, :mod:`sequences.metadata`; a field not given is
        recorded empty). ``flush_interval_s`` and ``clock`` (wall seconds) set the flush cadence;
        tests pass a simulated clock."""
        path = Path(path)
        stated = _checked_metadata(path, metadata)  # before the file exists: a refusal leaves none
        _hold(path, "choose another name")
        try:
            file = h5py.File(path, "x", libver=s.LIBVER, track_order=True, fs_strategy=s.FS_STRATEGY)
        except FileExistsError as err:
            locks.release(s.campaign_key(path))
            raise StoreError(path, "", "exists already; resume it or choose another name") from err
        except OSError as err:
            locks.release(s.campaign_key(path))
            raise StoreError(path, "", f"cannot be created ({err})") from err
        attrs = file.attrs
        attrs["schema"] = s.SCHEMA_NAME
        attrs["schema_version"] = s.SCHEMA_VERSION
        attrs["software_version"] = software_version
        attrs["created"] = _now_iso()
        attrs["config_name"] = config_name
        attrs["config_toml"] = config_toml
        attrs["sequence_name"] = sequence_name
        attrs["sequence_toml"] = sequence_toml
        attrs.update(stated)
        file.create_group(s.RUNS, track_order=True)
        _create_table(file, s.EVENTS, s.EVENT_DTYPE)
        writer = cls(file, path, flush_interval_s=flush_interval_s, clock=clock, metadata=stated)
        writer.flush()
        return writer

    @classmethod
    def open_append(
        cls,
        path: str | Path,
        *,
        metadata: Mapping[str, str] | None = None,
        flush_interval_s: float = s.FLUSH_INTERVAL_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> CampaignWriter:
        """Reopen a campaign file to resume it or add runs to it; the file is checked by the reader
        first, so a file that does not follow the schema is refused before anything is written to
        it. ``metadata``: what this session states (docs/hdf5.md, *Test metadata*): a sensor or tyre
        the campaign recorded otherwise is refused; a field the campaign left empty is filled in
        (a ``metadata`` event of ``/events`` says so); the runs begun from here record this
        session's bench, operator and notes."""
        path = Path(path)
        stated = _checked_metadata(path, metadata)
        _hold(path, "wait until it has finished")
        try:
            with open_campaign(path) as campaign:
                if campaign.schema_version != s.SCHEMA_VERSION:
                    raise StoreError(
                        path,
                        "/@schema_version",
                        f"is {campaign.schema_version}: this software adds runs to version {s.SCHEMA_VERSION}"
                        " files only (it reads the file; record into a new campaign file)",
                    )
                check_specimen(path, campaign.metadata, stated)
                filled = {k: v for k, v in stated.items() if v and not campaign.metadata[k]}
            try:
                file = h5py.File(path, "r+")
            except OSError as err:
                raise StoreError(path, "", f"cannot be opened for writing ({err})") from err
            _rebuild_table(file, s.EVENTS, s.EVENT_DTYPE)
        except BaseException:
            locks.release(s.campaign_key(path))
            raise
        writer = cls(file, path, flush_interval_s=flush_interval_s, clock=clock, metadata=stated)
        if filled:
            file.attrs.update(filled)
            shown = ", ".join(f"{name} = {value!r}" for name, value in filled.items())
            writer.add_event(
                EventKind.METADATA, f"recorded what the campaign had left empty: {shown}", **filled
            )
            writer.flush()
        return writer

    def __enter__(self) -> CampaignWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def run_ids(self) -> tuple[str, ...]:
        return tuple(self._file[s.RUNS])

    def begin_run(
        self,
        run_id: str,
        *,
        kind: str,
        step: Mapping[str, Any],
        conditions: Mapping[str, Any],
        channels: Sequence[Channel],
        sample_rate_hz: float,
        resumes: str | None = None,
        drive: Mapping[str, Any] | None = None,
    ) -> RunWriter:
        """Create ``/runs/<run_id>`` with its channels, points, events and link counters.

        ``step``: the sequence step that produced the run (JSON-able mapping); ``conditions``: what
        the operator answered or the bench was set to (tyre pressure, wheel fitted, ...); ``drive``:
        a road replay's drive, where it came from and its checksum (JSON-able mapping; the ``drive``
        attribute, written only when given).
        ``resumes``: the id of an incomplete run of the same step whose remaining points this run
        takes over; points that run has done cannot be done again here.
        """
        where = f"/{s.RUNS}/{run_id}"
        self._check_no_open_run(where)
        if not run_id or "/" in run_id or run_id == ".":
            raise StoreError(self.path, where, f"run id {run_id!r} cannot name an HDF5 group")
        if run_id in self._file[s.RUNS]:
            raise StoreError(self.path, where, "exists already: continue it or give a new run id")
        if kind not in RUN_KINDS:
            raise StoreError(self.path, where, f"kind {kind!r} is not one of {', '.join(RUN_KINDS)}")
        if not (np.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise StoreError(self.path, where, f"sample rate {sample_rate_hz} Hz must be positive")
        _check_channels(self.path, where, channels)
        done_before: frozenset[int] = frozenset()
        if resumes is not None:
            done_before = self._resumable(resumes)
        step_json = s.to_json(step, path=self.path, where=f"{where}@step")
        conditions_json = s.to_json(conditions, path=self.path, where=f"{where}@conditions")
        drive_json = s.to_json(drive, path=self.path, where=f"{where}@drive") if drive else ""

        group = self._file[s.RUNS].create_group(run_id, track_order=True)
        group.attrs.update(
            {
                "kind": str(kind),  # the plain word: HDF5 stores no str subclass
                "status": str(RunStatus.INCOMPLETE),
                "reason": "",
                "started": _now_iso(),
                "finished": "",
                "step": step_json,
                "conditions": conditions_json,
                "sample_rate_hz": float(sample_rate_hz),
                "resumes": resumes or "",
                "resumed_by": "",
                **{name: self.metadata[name] for name in s.RUN_METADATA_FIELDS},
                **({"drive": drive_json} if drive_json else {}),
            }
        )
        channel_group = group.create_group(s.CHANNELS, track_order=True)
        for spec in channels:
            ds = channel_group.create_dataset(
                spec.name,
                shape=(0,),
                maxshape=(None,),
                dtype=np.dtype(spec.dtype).newbyteorder("<"),
                chunks=(max(1, int(sample_rate_hz * self.flush_interval_s)),),
                compression="gzip",
                compression_opts=s.GZIP_LEVEL,
                shuffle=True,
            )
            ds.attrs.update(
                {"unit": spec.unit, "description": spec.description, "sample_rate_hz": float(sample_rate_hz)}
            )
            if spec.role is not None:
                ds.attrs["role"] = spec.role.value
        _create_table(group, s.POINTS, s.POINT_DTYPE)
        _create_table(group, s.EVENTS, s.EVENT_DTYPE)
        group.create_group(s.LINK)
        group.create_group(s.RESULTS, track_order=True)
        if resumes is not None:
            self._file[s.RUNS][resumes].attrs["resumed_by"] = run_id
        self._run = RunWriter(self, group, done_before=done_before)
        self.flush()
        return self._run

    def continue_run(self, run_id: str) -> RunWriter:
        """Go on writing the run ``run_id`` that did not complete (killed: ``incomplete``; or ended
        ``aborted``, ``interlocked``, ``e-stopped``, ``failed``) after its last durable sample: new
        samples are appended, new points and events added; a ``"resumed"`` event marks the place
        and keeps how the run had ended, and the run reads ``incomplete`` until it finishes again.
        The samples of the point that was interrupted stay in the arrays, unreferenced by any done
        point; the engine repeats that point."""
        where = f"/{s.RUNS}/{run_id}"
        self._check_no_open_run(where)
        done = self._resumable(run_id)
        group = self._file[s.RUNS][run_id]
        for dataset in group[s.CHANNELS].values():  # before anything changes
            _check_pipeline(self.path, dataset)
        ended = {"status": str(group.attrs["status"]), "reason": str(group.attrs["reason"])}
        group.attrs.update({"status": str(RunStatus.INCOMPLETE), "reason": "", "finished": ""})
        # what reads back of each channel (a writer killed inside a flush can leave its last chunks
        # unreadable); cut to the common length (it can die between two channels' appends too)
        channels = group[s.CHANNELS].values()
        usable = min((readable_length(dataset, dataset.shape[0]) for dataset in channels), default=0)
        for dataset in channels:
            if dataset.shape[0] > usable:
                dataset.resize((usable,))
        _rebuild_table(group, s.POINTS, s.POINT_DTYPE)
        _rebuild_table(group, s.EVENTS, s.EVENT_DTYPE)
        self._run = RunWriter(self, group, done_before=done)
        # the run keeps the bench, operator and notes it began with; who resumed it is in the event
        resumer = {name: self.metadata[name] for name in s.RUN_METADATA_FIELDS if self.metadata[name]}
        if ended["status"] == RunStatus.INCOMPLETE:
            text = f"writing resumed after sample {usable}"
            self._run.add_event(EventKind.RESUMED, text, samples=usable, **resumer)
        else:
            self._run.add_event(
                EventKind.RESUMED,
                f"writing resumed after sample {usable}; the run had ended {ended['status']}"
                + (f": {ended['reason']}" if ended["reason"] else ""),
                samples=usable,
                ended=ended["status"],
                ended_reason=ended["reason"],
                **resumer,
            )
        self.flush()
        return self._run

    def add_event(self, kind: EventKind, text: str, /, **fields: Any) -> None:
        """A campaign-level event (``/events``), for what happens between runs: prompts and their
        answers, hydraulics, tare. ``sample`` is -1 there."""
        _append_event(self._file[s.EVENTS], path=self.path, sample=-1, kind=kind, text=text, fields=fields)
        self.flush_if_due()

    def flush(self) -> None:
        """Make durable what can be written safely: the whole chunks of samples, the point rows
        whose samples they hold, events, attributes; HDF5 flush, then fsync of the file."""
        self._flush(final=False, sync=True)

    def _flush(self, *, final: bool, sync: bool) -> None:
        """``final``: the run ends, so its last partial chunk is written too; ``sync``: fsync the
        file (also done when the flush interval of wall time has passed since the last fsync)."""
        if self._run is not None:
            self._run._write_pending(final=final)
        self._file.flush()
        now_s = self._clock()
        if sync or now_s - self._last_sync_wall_s >= self.flush_interval_s:
            os.fsync(self._file.id.get_vfd_handle())
            self._last_sync_wall_s = now_s
        if self._run is not None:
            self._run._flushed()

    def flush_if_due(self) -> bool:
        """Flush when the open run's unwritten samples fill a chunk (one flush interval of
        samples), with an fsync only if the interval's wall time has passed since the last one;
        or flush and fsync when the interval's wall time has passed since the last fsync. Returns
        whether it flushed. Every write calls it."""
        run = self._run
        if run is not None and run._samples - run._written >= run.chunk_samples:
            self._flush(final=False, sync=False)
            return True
        if self._clock() - self._last_sync_wall_s >= self.flush_interval_s:
            self._flush(final=False, sync=True)
            return True
        return False

    def close(self) -> None:
        if self._file.id.valid:
            try:
                self._flush(final=True, sync=True)
                self._file.close()
            finally:
                locks.release(s.campaign_key(self.path))
        self._run = None

    def _check_no_open_run(self, where: str) -> None:
        if self._run is not None and self._run.is_open:
            raise StoreError(
                self.path, where, f"run {self._run.run_id!r} is still being written: finish it first"
            )

    def _resumable(self, run_id: str) -> frozenset[int]:
        """The done point indices of the run ``run_id`` that did not complete (and the runs it
        resumes)."""
        where = f"/{s.RUNS}/{run_id}"
        runs = self._file[s.RUNS]
        if run_id not in runs:
            raise StoreError(self.path, where, "no such run to resume")
        attrs = runs[run_id].attrs
        if attrs["status"] == "complete":
            raise StoreError(self.path, where, "is complete; only a run that did not complete can be resumed")
        if attrs["resumed_by"]:
            raise StoreError(self.path, where, f"was resumed already by run {attrs['resumed_by']!r}")
        done = _done_indices(runs[run_id][s.POINTS])
        if attrs["resumes"]:
            done |= _chain_done(runs, attrs["resumes"])
        return frozenset(done)

    def _run_closed(self, run: RunWriter) -> None:
        if self._run is run:
            self._flush(final=True, sync=True)
            self._run = None


class RunWriter:
    """Writes one run: sample blocks, point rows, events, link counters, results, its end."""

    def __init__(self, campaign: CampaignWriter, group: h5py.Group, *, done_before: frozenset[int]) -> None:
        self._campaign = campaign
        self._group = group
        self.run_id = group.name.rsplit("/", 1)[-1]
        self.sample_rate_hz = float(group.attrs["sample_rate_hz"])
        datasets = group[s.CHANNELS]
        self._names = frozenset(datasets)
        self._sinks = [_ChannelSink(campaign.path, ds) for ds in datasets.values()]
        self.chunk_samples = self._sinks[0].chunk_samples
        self._samples = min(ds.shape[0] for ds in datasets.values())
        self._written = self._durable_samples = self._samples
        # the pending samples start at a chunk boundary: a partial last chunk (a run closed
        # unfinished) is read back and written again whole once it fills
        self._origin = self._samples // self.chunk_samples * self.chunk_samples
        for sink in self._sinks:
            sink.reload(self._origin, self._samples)
        self._points, self._events = group[s.POINTS], group[s.EVENTS]
        self._pending_rows: list[np.ndarray] = []  # point rows waiting for their samples
        self._done = frozenset(_done_indices(self._points)) | done_before
        self.is_open = True

    @property
    def samples(self) -> int:
        """Samples appended so far (durable or not)."""
        return self._samples

    @property
    def durable_samples(self) -> int:
        """Samples made durable by the last flush (whole chunks until the run ends): they survive a
        killed writer; a power loss too once the next fsync has run (within the flush interval of
        wall time)."""
        return self._durable_samples

    def append(self, columns: Mapping[str, np.ndarray]) -> None:
        """Append one block: a 1-D array per channel of the run, all of one length. Integer
        channels take integer arrays whose values their dtype holds (else refused, naming the
        channel); float channels are stored as float32. The block is copied (the caller may reuse
        its buffers); a refused block leaves nothing behind."""
        if not self.is_open or columns.keys() != self._names:
            where = f"{self._group.name}/{s.CHANNELS}"
            self._check_open(where)
            missing, extra = self._names - columns.keys(), columns.keys() - self._names
            raise StoreError(
                self._campaign.path,
                where,
                f"block channels differ: missing {sorted(missing)}, unknown {sorted(extra)}",
            )
        arrays = [sink.checked(columns[sink.name]) for sink in self._sinks]
        n = arrays[0].shape[0]
        if any(array.shape[0] != n for array in arrays):
            lengths = {sink.name: array.shape[0] for sink, array in zip(self._sinks, arrays, strict=True)}
            raise StoreError(
                self._campaign.path,
                f"{self._group.name}/{s.CHANNELS}",
                f"block channels have different lengths: {lengths}",
            )
        if n == 0:
            return
        at = self._samples - self._origin
        for sink, array in zip(self._sinks, arrays, strict=True):
            sink.put(at, array)
        self._samples += n
        self._campaign.flush_if_due()

    def add_point(self, row: PointAttempt) -> None:
        """Add one row to the points table. A point index can be ``"done"`` once only in a step
        (this run and the runs it resumes); its sample positions must lie in what was recorded.
        The row goes to the file with the flush that writes its last sample, never before."""
        where = f"{self._group.name}/{s.POINTS}"
        self._check_open(where)
        if row.status not in s.POINT_STATUSES:
            raise StoreError(
                self._campaign.path, where, f"status {row.status!r} not one of {s.POINT_STATUSES}"
            )
        if row.status == PointStatus.DONE and row.index in self._done:
            raise StoreError(self._campaign.path, where, f"point {row.index} is done already")
        order = (
            0,
            row.start_sample,
            row.hold_start_sample,
            row.hold_end_sample,
            row.end_sample,
            self._samples,
        )
        if any(a > b for a, b in pairwise(order)):
            raise StoreError(
                self._campaign.path,
                where,
                f"point {row.index}: samples start {row.start_sample} <= hold {row.hold_start_sample}.."
                f"{row.hold_end_sample} <= end {row.end_sample} <= recorded {self._samples} do not hold",
            )
        record = np.array([tuple(getattr(row, name) for name in s.POINT_DTYPE.names)], dtype=s.POINT_DTYPE)
        self._pending_rows.append(record)
        if row.status == PointStatus.DONE:
            self._done |= {row.index}
        self._campaign.flush_if_due()

    def add_event(self, kind: EventKind, text: str, /, **fields: Any) -> None:
        """An event of this run (prompt and answer, interlock, state change, link gap, ...), at the
        current sample position; ``fields`` are stored as JSON."""
        self._check_open(f"{self._group.name}/{s.EVENTS}")
        _append_event(
            self._events,
            path=self._campaign.path,
            sample=self._samples,
            kind=kind,
            text=text,
            fields=fields,
        )
        self._campaign.flush_if_due()

    def set_link_counters(self, counters: Mapping[str, int | float]) -> None:
        """Replace the link counters (frames, gaps, CRC rejects, Modbus retries, ...) as attributes."""
        link = self._group[s.LINK]
        self._check_open(link.name)
        for key, value in counters.items():
            if not isinstance(value, int | float | np.integer | np.floating) or isinstance(value, bool):
                raise StoreError(
                    self._campaign.path, f"{link.name}@{key}", f"counter {value!r} is not a number"
                )
            link.attrs[key] = value
        self._campaign.flush_if_due()

    def write_results(self, name: str, result: Mapping[str, Any] | object) -> None:
        """Store an analysis result (a nested mapping or a dataclass instance) under
        ``results/<name>``; a name is written once (a re-analysis writes a new name). Results may
        be written after :meth:`finish` (the analysis runs after the run)."""
        _write_results(self._campaign.path, self._group, name, result)
        self._campaign.flush()

    def write_analysis_record(self, text: str) -> None:
        """Store the run's analysis record (a JSON text, docs/hdf5.md) as ``analysis``; written once,
        also after :meth:`finish` (the analysis runs after the run)."""
        _write_analysis_record(self._campaign.path, self._group, text)
        self._campaign.flush()

    def write_figure(self, name: str, png: bytes, shows_sha256: str) -> None:
        """Keep a figure the post-run analysis drew after the run as ``figures/<name>`` (PNG bytes;
        docs/hdf5.md), with the SHA-256 of what it shows; a name is written once per run. Durable at
        the next :meth:`flush` (the figures of one analysis are flushed together)."""
        figures = self._group.require_group(s.FIGURES)
        if name in figures:
            where = f"{figures.name}/{name}"
            raise StoreError(self._campaign.path, where, "exists already: a figure is kept once")
        dataset = figures.create_dataset(name, data=np.frombuffer(png, dtype=np.uint8))
        dataset.attrs[s.FIGURE_SHOWS] = shows_sha256
        dataset.attrs[s.FIGURE_PNG] = hashlib.sha256(png).hexdigest()

    def flush(self) -> None:
        self._campaign.flush()

    def finish(self, status: str, reason: str = "") -> None:
        """End the run with ``status`` (one of :data:`~bench.store.schema.FINISH_STATUSES`) and why."""
        self._check_open(self._group.name)
        if status not in FINISH_STATUSES:
            raise StoreError(
                self._campaign.path, self._group.name, f"status {status!r} not one of {FINISH_STATUSES}"
            )
        self._group.attrs.update({"status": str(status), "reason": reason, "finished": _now_iso()})
        self.is_open = False
        self._campaign._run_closed(self)

    def _write_pending(self, *, final: bool) -> None:
        """Write the whole chunks the pending samples fill (and the last partial one when
        ``final``), one extent change per channel and one write per chunk, then the point rows
        whose samples are written."""
        chunk = self.chunk_samples
        upto = self._samples if final else self._samples // chunk * chunk
        if upto > self._written:
            for sink in self._sinks:
                sink.write(self._origin, upto)
            self._written = upto
            whole = (upto - self._origin) // chunk * chunk
            for sink in self._sinks:
                sink.drop(whole, self._samples - self._origin)
            self._origin += whole
        ready = [row for row in self._pending_rows if row["end_sample"][0] <= self._written]
        if ready:
            _append_rows(self._points, np.concatenate(ready))
            self._pending_rows = [row for row in self._pending_rows if row["end_sample"][0] > self._written]

    def _flushed(self) -> None:
        self._durable_samples = self._written

    def _check_open(self, where: str) -> None:
        if not self.is_open and not where.startswith(f"{self._group.name}/{s.RESULTS}"):
            raise StoreError(self._campaign.path, where, f"run {self.run_id!r} is finished")


class _ChannelSink:
    """One channel of the run being written: checks a block's values against the channel's dtype,
    keeps the pending samples in a buffer that begins at a chunk boundary, and writes whole chunks
    of it through the channel's filter pipeline (:func:`_filtered_chunk`) as finished chunks, so
    that per chunk HDF5 only records where it lies."""

    def __init__(self, path: Path, dataset: h5py.Dataset) -> None:
        self.name = dataset.name.rsplit("/", 1)[-1]
        self._path = path
        self._where = dataset.name
        self._dataset = dataset
        self._id = dataset.id
        self.dtype = dataset.dtype
        self.chunk_samples = _check_pipeline(path, dataset)
        self._limits = None if self.dtype.kind == "f" else _DTYPE_LIMITS[self.dtype.str[1:]]
        self._buffer = np.zeros(2 * self.chunk_samples, self.dtype)

    def checked(self, values: np.ndarray) -> np.ndarray:
        """``values`` as an array this channel can store, else a :class:`StoreError` naming it."""
        array = np.asarray(values)
        if array.ndim != 1:
            raise StoreError(self._path, self._where, f"a block must be 1-D, got shape {array.shape}")
        if self._limits is None:
            return array  # a float channel stores any number as float32
        if array.dtype.kind not in "iu":
            raise StoreError(self._path, self._where, f"{self.dtype} channel given {array.dtype} values")
        if np.can_cast(array.dtype, self.dtype):
            return array  # every value of a narrower unsigned type fits
        low, high = self._limits
        if array.size and (array.min() < low or array.max() > high):
            raise StoreError(
                self._path,
                self._where,
                f"values {array.min()}..{array.max()} outside {self.dtype} ({low}..{high})",
            )
        return array

    def put(self, at: int, array: np.ndarray) -> None:
        """Copy ``array`` into the buffer from position ``at`` (converted to the channel's dtype)."""
        end = at + array.shape[0]
        if end > self._buffer.shape[0]:
            grown = np.zeros(max(end, 2 * self._buffer.shape[0]), self.dtype)
            grown[:at] = self._buffer[:at]
            self._buffer = grown
        self._buffer[at:end] = array

    def reload(self, origin: int, length: int) -> None:
        """Put the samples ``origin .. length`` already in the file back into the buffer."""
        self._buffer[: length - origin] = self._dataset[origin:length]

    def write(self, origin: int, upto: int) -> None:
        """Extend the dataset to ``upto`` samples and write the chunks from ``origin`` (a chunk
        boundary, the buffer's start) that hold samples below ``upto``; a partial last chunk is
        filled with zeros, the dataset's fill value, as HDF5 fills it."""
        self._id.set_extent((upto,))
        chunk = self.chunk_samples
        for start in range(0, upto - origin, chunk):
            block = self._buffer[start : start + chunk]
            if start + chunk > upto - origin:
                block = np.zeros(chunk, self.dtype)
                block[: upto - origin - start] = self._buffer[start : upto - origin]
            self._id.write_direct_chunk((origin + start,), _filtered_chunk(block))

    def drop(self, n: int, pending: int) -> None:
        """Forget the first ``n`` buffered samples (written); ``pending`` samples are buffered."""
        if n:
            self._buffer[: pending - n] = self._buffer[n:pending]


def _write_results(path: Path, run: h5py.Group, name: str, result: Mapping[str, Any] | object) -> None:
    """``result`` under ``run/results/<name>``, refused if the name is taken (never overwritten)."""
    where = f"{run.name}/{s.RESULTS}/{name}"
    tree = as_mapping(result)
    if tree is None:
        raise StoreError(path, where, f"a result must be a mapping, got {type(result).__name__}")
    results = run[s.RESULTS]
    if not name or "/" in name or name == ".":
        raise StoreError(path, where, f"name {name!r} cannot name an HDF5 group")
    if name in results:
        raise StoreError(path, where, "exists already: results are never overwritten")
    _check_stored_key(path, where, tree)
    group = results.create_group(name)
    write_tree(group, tree, path=path)
    group.attrs[s.RESULT_STORED] = _now_iso()


def _write_analysis_record(path: Path, run: h5py.Group, text: str) -> None:
    """The run's analysis record as ``run/analysis``, refused if it has one (never overwritten)."""
    if s.ANALYSIS in run:
        where = f"{run.name}/{s.ANALYSIS}"
        raise StoreError(path, where, "exists already: an analysis record is written once")
    run.create_dataset(s.ANALYSIS, data=text, dtype=s.STR).attrs[s.RESULT_STORED] = _now_iso()


def _check_stored_key(path: Path, where: str, result: Mapping[str, Any] | object) -> None:
    """A result's own top-level key may not take the name of the attribute that says when it was
    stored (:data:`~bench.store.schema.RESULT_STORED`)."""
    if s.RESULT_STORED in (as_mapping(result) or {}):
        raise StoreError(path, f"{where}/{s.RESULT_STORED}", "is the attribute saying when it was stored")


def add_results(
    path: str | Path,
    results: Mapping[tuple[str, str], Mapping[str, Any] | object],
    analysis_records: Mapping[str, str] | None = None,
) -> None:
    """Store the results of a re-analysis beside the runs of the campaign file at ``path``:
    ``results`` maps (run id, result name) to a result; ``analysis_records``, run id to its analysis
    record, for the runs that have none (a run's record is written once: one it has is kept). The
    file is checked by the reader first; every name must be new (checked for all before anything is
    written: a refused re-analysis leaves the file as it was). No file may be open for writing by a
    run at the same time."""
    path = Path(path)
    _hold(path, "analyse it once that has finished")
    try:
        _add_results(path, results, analysis_records or {})
    finally:
        locks.release(s.campaign_key(path))


def _checked_metadata(path: Path, metadata: Mapping[str, str] | None) -> dict[str, str]:
    """Every metadata field as stated (empty when not), each value checked
    (:func:`~sequences.metadata.metadata_value`); a refusal names the attribute."""
    for name, value in (metadata or {}).items():
        try:
            metadata_value(name, value)
        except ValueError as err:
            raise StoreError(path, f"/@{name}", str(err)) from None
    return merged(metadata or {})


def check_specimen(path: Path, recorded: Mapping[str, str], stated: Mapping[str, str]) -> None:
    """Refuse a session that states another sensor or tyre than the campaign recorded
    (:func:`~sequences.metadata.specimen_conflicts`): one campaign file, one specimen."""
    conflicts = specimen_conflicts(recorded, stated)
    if conflicts:
        name, now, before = conflicts[0]
        more = f" (and {', '.join(c[0] for c in conflicts[1:])})" if conflicts[1:] else ""
        raise StoreError(
            path,
            f"/@{name}",
            f"{now!r} now, {before!r} in the file{more}: one campaign file holds one sensor and one"
            " tyre; record another specimen into another file",
        )


def _hold(path: Path, advice: str) -> None:
    """Take the campaign file's writer lock (:mod:`bench.locks`; re-entrant in one process, released
    by the writer's close); :class:`~bench.store.schema.CampaignInUseError` if another process has it."""
    try:
        locks.acquire(s.campaign_key(path), f"the campaign file {path}")
    except locks.InUseError as exc:
        raise s.CampaignInUseError(path, exc.holder, advice) from None


def _add_results(
    path: Path, results: Mapping[tuple[str, str], Mapping[str, Any] | object], records: Mapping[str, str]
) -> None:
    open_campaign(path).close()
    try:
        file = h5py.File(path, "r+")
    except OSError as err:
        raise StoreError(path, "", f"cannot be opened for writing ({err})") from err
    with file:
        runs = file[s.RUNS]
        for (run_id, name), result in results.items():
            where = f"/{s.RUNS}/{run_id}/{s.RESULTS}/{name}"
            if run_id not in runs:
                raise StoreError(path, f"/{s.RUNS}/{run_id}", "no such run")
            if name in runs[run_id][s.RESULTS]:
                raise StoreError(path, where, "exists already: results are never overwritten")
            _check_stored_key(path, where, result)
        for run_id in records:
            if run_id not in runs:
                raise StoreError(path, f"/{s.RUNS}/{run_id}", "no such run")
        for (run_id, name), result in results.items():
            _write_results(path, runs[run_id], name, result)
        for run_id, text in records.items():
            if s.ANALYSIS not in runs[run_id]:
                _write_analysis_record(path, runs[run_id], text)
        file.flush()


def _check_pipeline(path: Path, dataset: h5py.Dataset) -> int:
    """The samples per chunk of a channel dataset, after checking that it is stored as
    :func:`_filtered_chunk` writes chunks: 1-D chunks, shuffle then gzip at
    :data:`~bench.store.schema.GZIP_LEVEL`, fill value 0."""
    plist = dataset.id.get_create_plist()
    filters = [(code, values) for code, _, values, _ in map(plist.get_filter, range(plist.get_nfilters()))]
    expected = [(h5z.FILTER_SHUFFLE, (dataset.dtype.itemsize,)), (h5z.FILTER_DEFLATE, (s.GZIP_LEVEL,))]
    if dataset.chunks is None or len(dataset.chunks) != 1 or filters != expected or dataset.fillvalue != 0:
        raise StoreError(
            path,
            dataset.name,
            f"stored with chunks {dataset.chunks}, filters {filters}, fill value {dataset.fillvalue}; "
            f"the writer appends to 1-D chunked channels, shuffled, gzip level {s.GZIP_LEVEL}, filled with 0",
        )
    return dataset.chunks[0]


def _filtered_chunk(chunk: np.ndarray) -> bytes:
    """A whole chunk of a channel as HDF5's filter pipeline stores it: the shuffle filter (the
    first bytes of every element, then the second bytes, ...), then deflate at
    :data:`~bench.store.schema.GZIP_LEVEL` (kept even when it does not shrink the chunk, as HDF5
    2.0 keeps it). Compressing here rather than in HDF5 lets other threads run meanwhile (``zlib``
    releases the GIL, HDF5 calls do not)."""
    shuffled = chunk.view(np.uint8).reshape(-1, chunk.itemsize).T.tobytes()
    return zlib.compress(shuffled, s.GZIP_LEVEL)


def _check_channels(path: Path, where: str, channels: Sequence[Channel]) -> None:
    names = [c.name for c in channels]
    if not names:
        raise StoreError(path, where, "a run needs at least one channel")
    if len(set(names)) != len(names):
        raise StoreError(path, where, f"channel names repeat: {names}")
    for spec in channels:
        if not spec.name or "/" in spec.name or spec.name == ".":
            raise StoreError(
                path, f"{where}/{s.CHANNELS}", f"channel name {spec.name!r} cannot name a dataset"
            )
        if spec.dtype not in s.CHANNEL_DTYPES:
            raise StoreError(
                path,
                f"{where}/{s.CHANNELS}/{spec.name}",
                f"dtype {spec.dtype!r} not one of {s.CHANNEL_DTYPES}",
            )


def _create_table(parent: h5py.Group, name: str, dtype: np.dtype) -> None:
    parent.create_dataset(
        name,
        shape=(0,),
        maxshape=(None,),
        dtype=dtype,
        chunks=(s.TABLE_CHUNK_ROWS,),
    )


def _rebuild_table(parent: h5py.Group, name: str, dtype: np.dtype) -> None:
    """Recreate a table with its rows before appending to it in a new session. A writer killed
    after writing rows into the table's last chunk but before flushing its new length leaves those
    rows' string references behind the table's end; HDF5 would try to free them when new rows are
    written over them, and fail. A fresh dataset has no such leftovers."""
    rows = parent[name][()]
    del parent[name]
    _create_table(parent, name, dtype)
    if rows.shape[0]:
        _append_rows(parent[name], _as_dtype(rows, dtype))


def _as_dtype(rows: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """``rows`` of a table written before fields were added, with the added fields' defaults."""
    if rows.dtype == dtype:
        return rows
    out = np.zeros(rows.shape, dtype=dtype)
    for name in dtype.names:
        out[name] = rows[name] if name in rows.dtype.names else s.OPTIONAL_POINT_FIELDS[name]
    return out


def _append_rows(table: h5py.Dataset, rows: np.ndarray) -> None:
    """Append ``rows`` to ``table`` through h5py's low-level calls: its high-level path rebuilds
    the compound's dtype and memory type on every call, which costs more than the write."""
    n = table.id.shape[0]
    table.id.set_extent((n + rows.shape[0],))
    file_space = table.id.get_space()
    file_space.select_hyperslab((n,), rows.shape)
    table.id.write(h5s.create_simple(rows.shape), file_space, rows, mtype=_memory_type(rows.dtype))


@cache
def _memory_type(dtype: np.dtype) -> h5t.TypeID:
    """The HDF5 memory type of a table's rows (variable-length strings as h5py hands them over)."""
    return h5t.py_create(dtype)


def _append_event(
    table: h5py.Dataset, *, path: Path, sample: int, kind: str, text: str, fields: Mapping[str, Any]
) -> None:
    fields_json = s.to_json(fields, path=path, where=f"{table.name} {kind!r} fields")
    row = np.array([(time.time(), sample, kind, text, fields_json)], dtype=s.EVENT_DTYPE)
    _append_rows(table, row)


def _done_indices(points: h5py.Dataset) -> set[int]:
    rows = points[()]
    return {
        int(i)
        for i, status in zip(rows["index"], rows["status"], strict=True)
        if _text(status) == PointStatus.DONE
    }


def _chain_done(runs: h5py.Group, run_id: str) -> set[int]:
    done: set[int] = set()
    seen: set[str] = set()
    while run_id and run_id not in seen and run_id in runs:
        seen.add(run_id)
        done |= _done_indices(runs[run_id][s.POINTS])
        run_id = runs[run_id].attrs["resumes"]
    return done


def _text(value: bytes | str) -> str:
    return value.decode() if isinstance(value, bytes) else value
