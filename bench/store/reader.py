"""Read a campaign file, whatever wrote it, into the analysis's records.

:func:`open_campaign` checks the whole file against the schema before returning (names, versions,
attributes, JSON texts, dtypes, every point's sample range), so a bad file is refused at once with
its path and the place inside it; sample data are read only when asked for. The analysis records
come from the points table: one :class:`~bench.analysis.records.DwellRecord` per done point,
sliced from the run's channels by its sample positions.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, fields
from itertools import pairwise
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from bench import locks
from bench.analysis.records import (
    DEFAULT_SETTLE_S,
    FREE_RUN_CHANNELS,
    SHAKER_CHANNELS,
    WFS_FORCE,
    WHEEL_CHANNELS,
    DwellRecord,
    HammerRecord,
    RoadReplayRecord,
    SweepRecord,
)
from bench.analysis.tracking import TrackRecord
from bench.numerics.sine_fit import frame_offsets
from bench.store import schema as s
from bench.store.results import read_tree
from bench.store.schema import StoreError
from sequences.channels import Channel, Role, standard_name
from sequences.points import PointAttempt, PointStatus, Verdict
from sequences.runs import FINISH_STATUSES, RUN_KINDS, EventKind, RunStatus

#: The recorded channel of the WFS frame counter (``bench.engine.channels``): the true sample times.
SEQ_CHANNEL = "seq"

#: Channels each kind of run needs for its analysis records. A dwell grid's wheel is on the shaker,
#: whose hub is clamped: its hub acceleration is recorded where the lab has it, never needed.
REQUIRED_CHANNELS = {
    "dwell_grid": SHAKER_CHANNELS,
    "free_run": FREE_RUN_CHANNELS,
    "sweep": WHEEL_CHANNELS,
    "hammer": (WFS_FORCE,),
    "tracked_dwell": FREE_RUN_CHANNELS,
    "road_replay": WHEEL_CHANNELS,
    "drive_iteration": WHEEL_CHANNELS,
}
_ROOT_TEXT_ATTRS = (
    "software_version",
    "created",
    "config_name",
    "config_toml",
    "sequence_name",
    "sequence_toml",
)
_RUN_TEXT_ATTRS = (
    "kind",
    "status",
    "reason",
    "started",
    "finished",
    "step",
    "conditions",
    "resumes",
    "resumed_by",
)
_SWEEP_KEYS = ("start_hz", "end_hz", "duration_s", "amplitude_mm")


@dataclass(frozen=True, slots=True)
class Event:
    """One row of an ``events`` table; ``sample`` is the run's recorded length when it happened
    (-1 for campaign-level events); ``kind`` as stored (an :class:`~sequences.runs.EventKind`'s word
    when this software wrote it; another program's word is kept as it is)."""

    time_unix_s: float
    sample: int
    kind: str
    text: str
    fields: Mapping[str, Any] = field(default_factory=dict)


def open_campaign(path: str | Path, *, while_written: bool = False) -> CampaignFile:
    """Open and check the campaign file at ``path``; close it with ``close()`` or a ``with`` block.

    ``while_written``: open it without HDF5's file lock, so that a file a run is writing can be
    looked at (the web monitor): what its writer has flushed is read, and a read that meets a flush
    under way fails as a :class:`StoreError` (try again). Never for anything that must be whole."""
    path = Path(path)
    if path.is_dir():
        raise StoreError(path, "", "a directory, not a campaign file (an HDF5 file, docs/hdf5.md)")
    if path.exists() and not path.is_file():  # a FIFO, a device, a socket: opening one may wait forever
        raise StoreError(path, "", "not a regular file, not a campaign file (an HDF5 file, docs/hdf5.md)")
    try:
        file = h5py.File(path, "r", locking=False) if while_written else h5py.File(path, "r")
    except FileNotFoundError as err:
        raise StoreError(path, "", "no such file") from err
    except OSError as err:
        if _locked(err):
            holder = locks.holder_of(s.campaign_key(path))
            raise s.CampaignInUseError(path, holder, "read it once that has finished") from None
        raise StoreError(path, "", f"not a readable HDF5 file ({_hdf5_reason(err)})") from err
    try:
        return CampaignFile(file, path)
    except BaseException:
        file.close()
        raise


def _locked(err: OSError) -> bool:
    """HDF5 refused the file because another process holds its file lock (it is being written)."""
    return "unable to lock file" in str(err) or "file is already open for write" in str(err)


def _hdf5_reason(err: OSError) -> str:
    """The reason of an HDF5 open error for a person: the system's message where HDF5 quotes one
    (without its dump of the read: buffer address, sizes, offsets), else HDF5's own."""
    text = str(err)
    quoted = re.search(r"error message = '([^']*)'", text)
    return quoted[1] if quoted else text.splitlines()[0]


@contextmanager
def _reading(path: Path, where: str) -> Iterator[None]:
    """HDF5's own errors (a truncated or damaged file) as a :class:`StoreError` naming ``where``."""
    try:
        yield
    except (OSError, RuntimeError, KeyError) as err:
        raise StoreError(path, where, f"unreadable ({err})") from err


#: Python type of each :class:`PointAttempt` field, by its annotation.
_FIELD_TYPES = {f.name: {"int": int, "float": float, "str": str}[f.type] for f in fields(PointAttempt)}


def _point_values(row: np.void, names: tuple[str, ...]) -> dict[str, Any]:
    """A points-table row as :class:`PointAttempt` fields; a version-1 row's ``corrected_amplitude_mm``
    (NaN: the step's amplitude was sent) and ``settled`` are read as the command sent and the verdict."""
    values: dict[str, Any] = {
        name: _text(row[name]) if kind is str else kind(row[name])
        for name, kind in _FIELD_TYPES.items()
        if name in names
    }
    if "commanded_amplitude_mm" not in names:
        corrected = float(row["corrected_amplitude_mm"])
        values["commanded_amplitude_mm"] = corrected if math.isfinite(corrected) else values["amplitude_mm"]
    if "settled" in names and not bool(row["settled"]) and not values.get("verdict"):
        values["verdict"] = Verdict.NOT_SETTLED
    return values


def _channel_role(path: Path, dataset: h5py.Dataset) -> Role | None:
    """A channel's ``role`` attribute (files without it, written before roles were recorded, name
    their channels by the roles' standard names)."""
    if "role" not in dataset.attrs:
        return None
    text = _attr(path, dataset, "role", str)
    try:
        return Role(text)
    except ValueError:
        roles = ", ".join(r.value for r in Role)
        raise StoreError(path, f"{dataset.name}@role", f"{text!r} is not a role ({roles})") from None


def _attr(path: Path, obj: h5py.HLObject, name: str, kind: type) -> Any:
    where = f"{obj.name}@{name}"
    if name not in obj.attrs:
        raise StoreError(path, where, "missing attribute")
    value = obj.attrs[name]
    if kind is str:
        if isinstance(value, bytes):
            value = value.decode()
        if not isinstance(value, str):
            raise StoreError(path, where, f"must be text, found {value!r}")
        return value
    if not isinstance(value, int | float | np.integer | np.floating) or isinstance(value, bool | np.bool_):
        raise StoreError(path, where, f"must be a number, found {value!r}")
    return kind(value)


def _optional_text(path: Path, obj: h5py.HLObject, name: str) -> str:
    """A text attribute that files may lack (written before it was recorded, or by another
    writer): empty when absent; refused when it holds something other than text."""
    return _attr(path, obj, name, str) if name in obj.attrs else ""


def _member(path: Path, group: h5py.Group, name: str, kind: type) -> Any:
    where = f"{group.name}/{name}".replace("//", "/")
    item = group.get(name)
    if item is None:
        raise StoreError(path, where, f"missing {'group' if kind is h5py.Group else 'dataset'}")
    if not isinstance(item, kind):
        raise StoreError(path, where, f"must be a {'group' if kind is h5py.Group else 'dataset'}")
    return item


def _text(value: bytes | str) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


class CampaignFile:
    """A checked campaign file: what produced it, its runs in the order they began, its events."""

    def __init__(self, file: h5py.File, path: Path) -> None:
        self._file, self.path = file, path
        with _reading(path, "/"):
            schema = _attr(path, file, "schema", str) if "schema" in file.attrs else None
            if schema != s.SCHEMA_NAME:
                raise StoreError(path, "/@schema", f"is {schema!r}, not a {s.SCHEMA_NAME!r} file")
            version = _attr(path, file, "schema_version", int)
            if version not in s.READABLE_VERSIONS:
                readable = " and ".join(map(str, s.READABLE_VERSIONS))
                raise StoreError(
                    path, "/@schema_version", f"is {version}; this software reads versions {readable}"
                )
            self.schema_version = version
            info = {name: _attr(path, file, name, str) for name in _ROOT_TEXT_ATTRS}
            self.software_version, self.created = info["software_version"], info["created"]
            self.config_name, self.config_toml = info["config_name"], info["config_toml"]
            self.sequence_name, self.sequence_toml = info["sequence_name"], info["sequence_toml"]
            #: the test metadata (docs/hdf5.md): every field, empty when the file does not give it
            self.metadata = {name: _optional_text(path, file, name) for name in s.METADATA_FIELDS}
            self.events = _read_events(path, _member(path, file, s.EVENTS, h5py.Dataset))
            runs = _member(path, file, s.RUNS, h5py.Group)
            self.runs = tuple(RunView(path, runs[run_id], self.run, version) for run_id in runs)
        self._by_id = {run.run_id: run for run in self.runs}

    def run(self, run_id: str) -> RunView:
        if run_id not in self._by_id:
            raise StoreError(
                self.path, f"/{s.RUNS}/{run_id}", f"no such run (runs: {', '.join(self._by_id)})"
            )
        return self._by_id[run_id]

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> CampaignFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Channels(Mapping[str, np.ndarray]):
    """A run's channels by their names in the file, each read from the file when asked for (its
    first ``n`` samples). :meth:`slice` names them as the analysis does: a channel recorded under a
    lab's own name with a role is given the role's standard name (``f_loadcell_n`` playing the
    plate force becomes ``f_plate_n``)."""

    def __init__(
        self, path: Path, datasets: Mapping[str, h5py.Dataset], n: int, specs: tuple[Channel, ...]
    ) -> None:
        self._path, self._datasets, self._n = path, datasets, n
        self.analysis_names = {spec.name: _analysis_name(spec) for spec in specs}

    def __getitem__(self, name: str) -> np.ndarray:
        ds = self._datasets[name]
        with _reading(self._path, ds.name):
            return ds[: self._n]

    def __iter__(self) -> Iterator[str]:
        return iter(self._datasets)

    def __len__(self) -> int:
        return len(self._datasets)

    def slice(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """Samples ``start`` to ``stop`` of every channel, by the analysis's names."""
        out = {}
        for name, ds in self._datasets.items():
            with _reading(self._path, ds.name):
                out[self.analysis_names[name]] = ds[start:stop]
        return out


def readable_length(dataset: h5py.Dataset, length: int) -> int:
    """How many of a killed writer's first ``length`` samples of ``dataset`` read back: ``length``
    cut to the start of the chunks at its end that do not. A writer killed inside a flush can leave
    a chunk that the file's index points to and that was not written whole, or lies beyond the
    file's end as last flushed (HDF5: "addr overflow"); that flush never returned, so its samples
    were never durable. Only chunks at the end are dropped: a damaged chunk before a readable one
    stays an error when read."""
    chunk = dataset.chunks[0] if dataset.chunks else max(length, 1)
    while length > 0:
        start = (length - 1) // chunk * chunk
        try:
            dataset[start:length]
        except (OSError, RuntimeError):
            length = start
            continue
        break
    return length


def _true_offsets(channels: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """The samples' true offsets from the first, from the frame counter ``seq`` where the run
    recorded it and frames were lost; None: the samples are contiguous (or the file has no
    counter, as an import of another system's export)."""
    seq = channels.get(SEQ_CHANNEL)
    if seq is None or len(seq) == 0:
        return None
    offsets = frame_offsets(seq)
    return None if offsets[-1] == len(offsets) - 1 else offsets


def _record_time(offsets: np.ndarray, i: int) -> int:
    """Record time (sample times) of sample ``i`` of a record whose samples lie at ``offsets``; the
    record's end (``i`` its length) lies one sample time after its last sample."""
    if len(offsets) == 0:
        return i
    return int(offsets[i] if i < len(offsets) else offsets[-1] + 1 + i - len(offsets))


def _analysis_name(spec: Channel) -> str:
    """The name the analysis knows ``spec`` by: its role's standard name, else its own."""
    if spec.role is None or spec.role is Role.SPARE:
        return spec.name
    return standard_name(spec.role)


@dataclass(frozen=True)
class StoredFigure:
    """A figure kept beside a run (docs/hdf5.md): its ``png`` bytes, the SHA-256 of what it shows and
    of the PNG as written. A member that is not laid out as a figure reads as empty bytes and
    digests, which match nothing: it is drawn again."""

    png: bytes
    shows_sha256: str
    png_sha256: str


def _stored_figure(item: object) -> StoredFigure:
    if not (isinstance(item, h5py.Dataset) and item.ndim == 1 and item.dtype == np.uint8):
        return StoredFigure(b"", "", "")
    attrs = {name: item.attrs.get(name) for name in (s.FIGURE_SHOWS, s.FIGURE_PNG)}
    if not all(isinstance(value, str) for value in attrs.values()):
        return StoredFigure(b"", "", "")
    return StoredFigure(item[()].tobytes(), attrs[s.FIGURE_SHOWS], attrs[s.FIGURE_PNG])


class RunView:
    """One checked run: attributes, channel specs, points, events; samples read on demand."""

    def __init__(
        self, path: Path, group: h5py.Group, lookup: Callable[[str], RunView], schema_version: int
    ) -> None:
        self.path, self._lookup = path, lookup
        where = group.name
        self.run_id = where.rsplit("/", 1)[-1]
        text = {name: _attr(path, group, name, str) for name in _RUN_TEXT_ATTRS}
        self.kind, self.status, self.reason = text["kind"], text["status"], text["reason"]
        self.started, self.finished = text["started"], text["finished"]
        self.resumes, self.resumed_by = text["resumes"] or None, text["resumed_by"] or None
        if self.kind not in RUN_KINDS:
            raise StoreError(path, f"{where}@kind", f"{self.kind!r} is not one of {', '.join(RUN_KINDS)}")
        if self.status not in (*FINISH_STATUSES, RunStatus.INCOMPLETE):
            raise StoreError(path, f"{where}@status", f"{self.status!r} is not a run status")
        self.step = s.from_json(text["step"], path=path, where=f"{where}@step")
        self.conditions = s.from_json(text["conditions"], path=path, where=f"{where}@conditions")
        #: a road replay's drive: where it came from and its checksum (empty for any other run)
        drive_text = _optional_text(path, group, "drive")
        self.drive = s.from_json(drive_text, path=path, where=f"{where}@drive") if drive_text else {}
        self.sample_rate_hz = _attr(path, group, "sample_rate_hz", float)
        #: the bench, operator and notes of the session that began the run (empty: not stated)
        self.metadata = {name: _optional_text(path, group, name) for name in s.RUN_METADATA_FIELDS}
        if not (math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise StoreError(path, f"{where}@sample_rate_hz", f"{self.sample_rate_hz} must be positive")
        datasets = self._channel_datasets(_member(path, group, s.CHANNELS, h5py.Group))
        lengths = {name: ds.shape[0] for name, ds in datasets.items()}
        if self.status == RunStatus.INCOMPLETE:
            lengths = {name: readable_length(datasets[name], n) for name, n in lengths.items()}
        self.n_samples = min(lengths.values(), default=0)
        if self.status != RunStatus.INCOMPLETE and len(set(lengths.values())) > 1:
            raise StoreError(
                path, f"{where}/{s.CHANNELS}", f"channels of a finished run differ in length: {lengths}"
            )
        self.channels = _Channels(path, datasets, self.n_samples, self.channel_specs)
        points = _member(path, group, s.POINTS, h5py.Dataset)
        self.points = _read_points(path, points, self.n_samples, schema_version)
        self.events = _read_events(path, _member(path, group, s.EVENTS, h5py.Dataset))
        self.link_counters = {
            k: v.item() if isinstance(v, np.generic) else v
            for k, v in _member(path, group, s.LINK, h5py.Group).attrs.items()
        }
        self._results = _member(path, group, s.RESULTS, h5py.Group)
        self._analysis = group.get(s.ANALYSIS)
        self._figures = group.get(s.FIGURES)
        if self._analysis is not None and not (
            isinstance(self._analysis, h5py.Dataset)
            and self._analysis.shape == ()
            and h5py.check_string_dtype(self._analysis.dtype) is not None
        ):
            raise StoreError(path, f"{where}/{s.ANALYSIS}", "the analysis record must be a string")

    def _channel_datasets(self, group: h5py.Group) -> dict[str, h5py.Dataset]:
        datasets = {}
        specs = []
        for name, item in group.items():
            where = f"{group.name}/{name}"
            if not isinstance(item, h5py.Dataset) or item.ndim != 1:
                raise StoreError(self.path, where, "a channel must be a 1-D dataset")
            if item.dtype.str[1:] not in s.CHANNEL_DTYPES:
                raise StoreError(self.path, where, f"dtype {item.dtype} is not one of {s.CHANNEL_DTYPES}")
            rate = _attr(self.path, item, "sample_rate_hz", float)
            if rate != self.sample_rate_hz:
                raise StoreError(self.path, f"{where}@sample_rate_hz", f"{rate} Hz differs from the run's")
            unit = _attr(self.path, item, "unit", str)
            description = _attr(self.path, item, "description", str)
            role = _channel_role(self.path, item)
            specs.append(Channel(name, unit, description, item.dtype.str[1:], role))
            datasets[name] = item
        analysis = [_analysis_name(spec) for spec in specs]
        for spec, known_as in zip(specs, analysis, strict=True):
            if analysis.count(known_as) > 1:
                raise StoreError(
                    self.path, f"{group.name}/{spec.name}", f"two channels are the {known_as} of the run"
                )
        self.channel_specs = tuple(specs)
        return datasets

    def figures(self) -> dict[str, StoredFigure]:
        """The figures the post-run analysis kept beside the run, by name (none before they were
        kept, or when the analysis drew none after this run)."""
        if not isinstance(self._figures, h5py.Group):
            return {}
        with _reading(self.path, self._figures.name):
            return {name: _stored_figure(item) for name, item in self._figures.items()}

    @property
    def analysis_record(self) -> str | None:
        """The run's analysis record as stored (JSON text: bench/app/analysis_record.py); None when
        the run has none (not analysed yet, or written before records were kept)."""
        if self._analysis is None:
            return None
        with _reading(self.path, self._analysis.name):
            return self._analysis.asstr()[()]

    @property
    def result_names(self) -> tuple[str, ...]:
        return tuple(self._results)

    def results(self, name: str) -> dict[str, Any]:
        """The stored result ``name`` as the nested mapping it was written from."""
        with _reading(self.path, f"{self._results.name}/{name}"):
            tree = read_tree(self._result_group(name), path=self.path)
        tree.pop(s.RESULT_STORED, None)
        return tree

    def result_stored(self, name: str) -> str:
        """When the result ``name`` was stored (ISO 8601 UTC); empty when the file does not say
        (results stored before the time was recorded, or by another writer)."""
        with _reading(self.path, f"{self._results.name}/{name}"):
            return _optional_text(self.path, self._result_group(name), s.RESULT_STORED)

    def _result_group(self, name: str) -> h5py.Group:
        where = f"{self._results.name}/{name}"
        if name not in self._results:
            raise StoreError(self.path, where, f"no such result (has {', '.join(self._results) or 'none'})")
        group = self._results[name]
        if not isinstance(group, h5py.Group):
            raise StoreError(self.path, where, "must be a group")
        return group

    def _chain(self) -> list[RunView]:
        """This run and the runs it resumes, oldest first."""
        chain, run = [self], self
        while run.resumes is not None:
            run = self._lookup(run.resumes)
            if run in chain:
                raise StoreError(
                    self.path, f"/{s.RUNS}/{run.run_id}@resumes", "runs resume each other in a loop"
                )
            chain.insert(0, run)
        return chain

    def completed_point_indices(self) -> frozenset[int]:
        """Indices of the step's points done in this run or in the runs it resumes: a resume skips
        them."""
        return frozenset(p.index for run in self._chain() for p in run.points if p.status == PointStatus.DONE)

    def _done_points(self) -> list[tuple[RunView, PointAttempt]]:
        done = [(run, p) for run in self._chain() for p in run.points if p.status == PointStatus.DONE]
        return sorted(done, key=lambda item: item[1].index)

    def _require(self, kinds: tuple[str, ...], what: str) -> None:
        if self.kind not in kinds:
            raise StoreError(self.path, f"/{s.RUNS}/{self.run_id}@kind", f"a {self.kind} run has no {what}")
        recorded = set(self.channels.analysis_names.values())
        missing = [c for c in REQUIRED_CHANNELS[self.kind] if c not in recorded]
        if missing:
            raise StoreError(
                self.path,
                f"/{s.RUNS}/{self.run_id}/{s.CHANNELS}/{missing[0]}",
                f"missing: a {self.kind} run needs {', '.join(REQUIRED_CHANNELS[self.kind])}"
                f" (it has {', '.join(self.channels)})",
            )

    def dwell_records(self) -> list[DwellRecord]:
        """One record per done point of a dwell grid or free run (and of the runs it resumes), in
        point order: the run's channels from ``start_sample`` to ``end_sample``, ``hold_s`` from the
        hold samples, the amplitude as commanded (``amplitude_mm``) and the grid's nominal amplitude
        when a bench limit lowered it (``requested_amplitude_mm``). An adaptive dwell's hold begins
        :data:`DEFAULT_SETTLE_S` before its measured part (not before the hold), so the analysis's
        settling allowance falls on samples the engine found settled and it fits the measured part."""
        self._require(("dwell_grid", "free_run"), "dwell records")
        records = []
        for run, p in self._done_points():
            channels = run.channels.slice(p.start_sample, p.end_sample)
            fs = run.sample_rate_hz
            offsets = _true_offsets(channels)
            at = np.arange(p.end_sample - p.start_sample) if offsets is None else offsets
            hold_start = _record_time(at, p.hold_start_sample - p.start_sample)
            if p.hold_start_sample <= p.measure_start_sample <= p.hold_end_sample:
                measure = _record_time(at, p.measure_start_sample - p.start_sample)
                hold_start = max(hold_start, measure - round(DEFAULT_SETTLE_S * fs))
            hold_s = (hold_start / fs, _record_time(at, p.hold_end_sample - p.start_sample) / fs)
            nominal_m = p.requested_amplitude_mm * 1e-3 if math.isfinite(p.requested_amplitude_mm) else None
            record = DwellRecord(p.freq_hz, p.amplitude_mm * 1e-3, fs, channels, hold_s, nominal_m, offsets)
            records.append(record)
        return records

    def _single_point(self, index: int) -> tuple[RunView, PointAttempt]:
        for run, p in self._done_points():
            if p.index == index:
                return run, p
        raise StoreError(self.path, f"/{s.RUNS}/{self.run_id}/{s.POINTS}", f"no done point {index}")

    def track_record(self) -> TrackRecord:
        """The track of a tracked dwell: its looks (the run's ``track`` events) and how it ended
        (its track point's verdict and note)."""
        self._require(("tracked_dwell",), "track record")
        looks = [e.fields for e in self.events if e.kind == EventKind.TRACK]
        done = [p for run, p in self._done_points() if p.verdict in (Verdict.TRACKED, Verdict.STOPPED)]

        def column(name: str) -> np.ndarray:
            return np.array([float(look[name]) for look in looks])

        return TrackRecord(
            self._true_time_s(column("sample").astype(np.int64)),
            column("drive_hz"),
            column("resonance_hz"),
            column("ratio"),
            column("phase_deg"),
            column("damping_ratio"),
            done[-1].verdict if done else "",
            done[-1].note if done else "",
        )

    def _true_time_s(self, ends: np.ndarray) -> np.ndarray:
        """The run's time (s) at run samples ``ends`` (each the sample after a window's last), by the
        frame counter where the run recorded it: frames lost before count as time."""
        seq = self.channels.get(SEQ_CHANNEL)
        if seq is None or len(seq) == 0 or len(ends) == 0:
            return ends / self.sample_rate_hz
        offsets = frame_offsets(seq)
        last = np.clip(ends - 1, 0, len(offsets) - 1)
        return (offsets[last] + 1 + (ends - 1 - last)) / self.sample_rate_hz

    def sweep_record(self) -> SweepRecord:
        """The sweep (point 0) with its start, end, duration and amplitude from the run's step."""
        self._require(("sweep",), "sweep record")
        missing = [k for k in _SWEEP_KEYS if not isinstance(self.step.get(k), int | float)]
        if missing:
            raise StoreError(
                self.path, f"/{s.RUNS}/{self.run_id}@step", f"no number for {', '.join(missing)}"
            )
        run, p = self._single_point(0)
        channels = run.channels.slice(p.start_sample, p.end_sample)
        step = self.step
        return SweepRecord(
            float(step["start_hz"]),
            float(step["end_hz"]),
            float(step["duration_s"]),
            float(step["amplitude_mm"]) * 1e-3,
            run.sample_rate_hz,
            channels,
            _true_offsets(channels),
        )

    def road_replay_record(self) -> RoadReplayRecord:
        """The road replay (point 0; a drive iteration's run's drive too): the run's channels over
        the drive, its hold (the part between its tapers) and the drive's source."""
        self._require(("road_replay", "drive_iteration"), "road replay record")
        run, p = self._single_point(0)
        fs = run.sample_rate_hz
        hold_s = ((p.hold_start_sample - p.start_sample) / fs, (p.hold_end_sample - p.start_sample) / fs)
        source = self.drive.get("source", "")
        return RoadReplayRecord(fs, run.channels.slice(p.start_sample, p.end_sample), hold_s, str(source))

    def hammer_record(self, blow: int = 0) -> HammerRecord:
        """Hammer blow ``blow`` (its point index) at the run's sample rate."""
        self._require(("hammer",), "hammer record")
        run, p = self._single_point(blow)
        return HammerRecord(run.sample_rate_hz, run.channels.slice(p.start_sample, p.end_sample))


def _read_points(path: Path, table: h5py.Dataset, n_samples: int, version: int) -> tuple[PointAttempt, ...]:
    names = () if table.dtype.names is None else table.dtype.names
    missing = [name for name in s.required_point_fields(version) if name not in names]
    if missing:
        raise StoreError(path, table.name, f"points table lacks field(s) {', '.join(missing)}")
    with _reading(path, table.name):
        rows = table[()]
    points = []
    for i, row in enumerate(rows):
        where = f"{table.name}[{i}]"
        p = PointAttempt(**_point_values(row, names))
        if p.status not in s.POINT_STATUSES:
            raise StoreError(path, f"{where}.status", f"{p.status!r} is not one of {s.POINT_STATUSES}")
        order = (p.start_sample, p.hold_start_sample, p.hold_end_sample, p.end_sample)
        if p.start_sample < 0 or any(a > b for a, b in pairwise(order)):
            raise StoreError(path, where, f"point {p.index}: sample positions {order} are not in order")
        if p.end_sample > n_samples:
            raise StoreError(
                path,
                where,
                f"point {p.index}: end_sample {p.end_sample} beyond the {n_samples} recorded samples",
            )
        points.append(p)
    return tuple(points)


def _read_events(path: Path, table: h5py.Dataset) -> tuple[Event, ...]:
    missing = [
        name for name in s.EVENT_DTYPE.names if table.dtype.names is None or name not in table.dtype.names
    ]
    if missing:
        raise StoreError(path, table.name, f"events table lacks field(s) {', '.join(missing)}")
    with _reading(path, table.name):
        rows = table[()]
    return tuple(
        Event(
            float(row["time_unix_s"]),
            int(row["sample"]),
            _text(row["kind"]),
            _text(row["text"]),
            s.from_json(_text(row["fields"]), path=path, where=f"{table.name}[{i}].fields"),
        )
        for i, row in enumerate(rows)
    )
