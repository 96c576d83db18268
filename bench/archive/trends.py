"""The archive's trends from an index (``wfsbench trends``): three figures and one page.

- ``tyre_stiffness``: each tyre's stiffness and damping against its pressure, from the model the
  analysis selected at each amplitude, with their 95 % intervals; a tyre is its ``tyre_id``, else
  its make and size;
- ``sensor_eigenfrequency``: each sensor's eigenfrequency from its hammer tests over time (the run's
  start), its calibration date marked;
- ``interlocks``: the runs that ended interlocked per bench and month (of the run's start).

The index is read column by column with filters (only the rows each figure needs), so an archive's
index of millions of rows is not loaded whole. The values are the index's own analysis
(``source`` ``analysis``): one software for every file. The page is self-contained like the
report's (docs/report.md): figures embedded, no external reference.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass
from datetime import date, datetime
from html import escape
from pathlib import Path

import pyarrow.compute as pc
import pyarrow.dataset as ds
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bench.archive import columns as c
from bench.archive.store import IndexDirError, check_part, part_paths
from bench.report.axes import DPI
from bench.report.figure_list import FigureFile

# the report page's style and builders, so that both pages look alike
from bench.report.html import PAGE_STYLE, figure_html, table_html

TRENDS_PAGE = "trends.html"
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


@dataclass(frozen=True)
class TyrePoint:
    """One tyre identification: the tyre, its pressure (bar) and amplitude (m), stiffness (N/m)
    and damping (Ns/m) of the selected model with their 95 % half-widths (None when not given)."""

    tyre: str
    pressure_bar: float
    amplitude_m: float
    stiffness_n_per_m: float
    stiffness_ci95_n_per_m: float | None
    damping_ns_per_m: float | None
    damping_ci95_ns_per_m: float | None


@dataclass(frozen=True)
class Eigenfrequency:
    serial: str
    at: datetime
    eigenfrequency_hz: float
    calibrated: date | None


def _dataset(index_dir: Path) -> ds.Dataset:
    parts = part_paths(index_dir)
    if not index_dir.is_dir():
        raise IndexDirError(f"{index_dir}: no such index directory")
    if not parts:
        raise IndexDirError(
            f"{index_dir}: an empty index (no part-*.parquet): index campaign files into it first"
        )
    for part in parts:
        check_part(part)
    return ds.dataset([str(p) for p in parts], schema=c.arrow_schema(), format="parquet")


def _analysis_values(
    data: ds.Dataset, analysis: str, parameters: tuple[str, ...], columns: list[str]
) -> list[dict]:
    where = (
        (ds.field("entry") == c.VALUE)
        & (ds.field("source") == "analysis")
        & (ds.field("analysis") == analysis)
        & ds.field("parameter").isin(parameters)
    )
    wanted = list(dict.fromkeys([*columns, "path", "sha256"]))
    return one_copy_each(data.to_table(columns=wanted, filter=where).to_pylist())


def one_copy_each(rows: list[dict]) -> list[dict]:
    """The rows of one file per content: a campaign copied under other paths (the same SHA-256)
    counts once, under the first of its paths in sort order."""
    first: dict[str, str] = {}
    for row in rows:
        first[row["sha256"]] = min(first.get(row["sha256"], row["path"]), row["path"])
    return [row for row in rows if row["path"] == first[row["sha256"]]]


def tyre_label(row: dict) -> str:
    """A tyre's name: its id, else its make and size, else ``unnamed tyre``."""
    return row["tyre_id"] or f"{row['tyre_make']} {row['tyre_size']}".strip() or "unnamed tyre"


def tyre_points(data: ds.Dataset) -> list[TyrePoint]:
    """Stiffness and damping of the selected model per tyre identification."""
    rows = _analysis_values(
        data,
        "shaker",
        ("stiffness_n_per_m", "damping_ns_per_m"),
        [
            "path",
            "run_id",
            "amplitude_m",
            "selected",
            "parameter",
            "value",
            "ci95",
            "tyre_pressure_bar",
            "tyre_id",
            "tyre_make",
            "tyre_size",
        ],
    )
    by_fit: dict[tuple, dict] = defaultdict(dict)
    for row in rows:
        if row["selected"] and row["value"] is not None:
            by_fit[row["path"], row["run_id"], row["amplitude_m"]][row["parameter"]] = row
    points = []
    for fit in by_fit.values():
        k, d = fit.get("stiffness_n_per_m"), fit.get("damping_ns_per_m")
        if k is None:
            continue
        points.append(
            TyrePoint(
                tyre_label(k),
                k["tyre_pressure_bar"],
                k["amplitude_m"],
                k["value"],
                k["ci95"],
                None if d is None else d["value"],
                None if d is None else d["ci95"],
            )
        )
    return sorted(points, key=lambda p: (p.tyre, p.pressure_bar, p.amplitude_m))


def eigenfrequencies(data: ds.Dataset) -> list[Eigenfrequency]:
    """Each hammer test's eigenfrequency by sensor serial, at the run's start."""
    rows = _analysis_values(
        data,
        "hammer",
        ("eigenfrequency_hz",),
        ["sensor_serial", "sensor_calibration_date", "run_started", "created", "value"],
    )
    out = [
        Eigenfrequency(
            row["sensor_serial"] or "unnamed sensor",
            row["run_started"] or row["created"],
            row["value"],
            _date(row["sensor_calibration_date"]),
        )
        for row in rows
        if row["value"] is not None and (row["run_started"] or row["created"]) is not None
    ]
    return sorted(out, key=lambda e: (e.serial, e.at))


def _date(text: str | None) -> date | None:
    try:
        return date.fromisoformat(text or "")
    except ValueError:
        return None


def interlocks(data: ds.Dataset) -> Counter[tuple[str, str]]:
    """Runs that ended interlocked, by (bench, month ``YYYY-MM`` of the run's start)."""
    where = (ds.field("entry") == c.RUN) & (ds.field("run_status") == "interlocked")
    columns = ["bench_id", "run_started", "created", "path", "sha256"]
    rows = one_copy_each(data.to_table(columns=columns, filter=where).to_pylist())
    return Counter(
        (row["bench_id"] or "unnamed bench", (row["run_started"] or row["created"]).strftime("%Y-%m"))
        for row in rows
        if (row["run_started"] or row["created"]) is not None
    )


def _figure(rows: int) -> tuple[Figure, list]:
    fig = Figure(figsize=(9, 3.2 * rows + 0.5), dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.1, right=0.97, top=0.95, bottom=0.24 if rows == 1 else 0.08, hspace=0.15)
    return fig, list(fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])


def tyre_figure(points: list[TyrePoint]) -> Figure:
    fig, (stiff, damp) = _figure(2)
    for n, tyre in enumerate(sorted({p.tyre for p in points})):
        mine = [p for p in points if p.tyre == tyre]
        style = {"marker": _MARKERS[n % len(_MARKERS)], "linestyle": "none", "capsize": 3, "label": tyre}
        x = [p.pressure_bar for p in mine]
        k_ci = [(p.stiffness_ci95_n_per_m or 0.0) / 1e3 for p in mine]
        stiff.errorbar(x, [p.stiffness_n_per_m / 1e3 for p in mine], yerr=k_ci, **style)
        with_d = [p for p in mine if p.damping_ns_per_m is not None]
        d_ci = [p.damping_ci95_ns_per_m or 0.0 for p in with_d]
        damp.errorbar(
            [p.pressure_bar for p in with_d], [p.damping_ns_per_m for p in with_d], yerr=d_ci, **style
        )
    stiff.set_ylabel("tyre stiffness (kN/m)")
    damp.set_ylabel("tyre damping (Ns/m)")
    damp.set_xlabel("tyre pressure (bar)")
    stiff.legend(fontsize=8, loc="upper left")
    for ax in (stiff, damp):
        ax.grid(alpha=0.3)
    return fig


def eigenfrequency_figure(values: list[Eigenfrequency]) -> Figure:
    fig, (ax,) = _figure(1)
    for n, serial in enumerate(sorted({v.serial for v in values})):
        mine = [v for v in values if v.serial == serial]
        line = ax.plot(
            [v.at for v in mine],
            [v.eigenfrequency_hz for v in mine],
            marker=_MARKERS[n % len(_MARKERS)],
            label=serial,
        )[0]
        for calibrated in sorted({v.calibrated for v in mine if v.calibrated is not None}):
            ax.axvline(
                datetime.combine(calibrated, datetime.min.time(), mine[0].at.tzinfo),
                color=line.get_color(),
                linestyle="--",
                alpha=0.6,
            )
    ax.set_ylabel("sensor eigenfrequency (Hz)")
    ax.set_xlabel("hammer test (dashed: calibration)")
    ax.legend(fontsize=8, loc="best", title="sensor serial")
    ax.grid(alpha=0.3)
    fig.autofmt_xdate()
    return fig


def interlock_figure(counts: Counter[tuple[str, str]]) -> Figure:
    fig, (ax,) = _figure(1)
    months = sorted({month for _, month in counts})
    benches = sorted({bench for bench, _ in counts})
    width = 0.8 / max(1, len(benches))
    for n, bench in enumerate(benches):
        x = [i + (n - (len(benches) - 1) / 2) * width for i in range(len(months))]
        ax.bar(x, [counts.get((bench, m), 0) for m in months], width, label=f"bench {bench}")
    ax.set_xticks(range(len(months)), months, rotation=45, ha="right")
    ax.set_ylabel("runs ended interlocked")
    ax.yaxis.get_major_locator().set_params(integer=True)
    if benches:
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    return fig


@dataclass(frozen=True)
class WrittenTrends:
    page: Path
    figures: tuple[FigureFile, ...]


def write_trends(index_dir: str | Path, out_dir: str | Path) -> WrittenTrends:
    """Draw the trends of the index at ``index_dir`` into ``out_dir/<name>.png`` and the page
    ``out_dir/trends.html`` (:class:`IndexDirError` for a missing, empty or foreign index)."""
    index_dir, out_dir = Path(index_dir), Path(out_dir)
    data = _dataset(index_dir)
    points, freqs, stops = tyre_points(data), eigenfrequencies(data), interlocks(data)
    drawn = [
        (
            "tyre_stiffness",
            "Tyre stiffness and damping against pressure",
            "Per tyre, the model selected at each amplitude; bars: 95 % intervals.",
            points,
            lambda: tyre_figure(points),
        ),
        (
            "sensor_eigenfrequency",
            "Sensor eigenfrequency over time",
            "Each hammer test by sensor serial; dashed: the sensor's calibration date.",
            freqs,
            lambda: eigenfrequency_figure(freqs),
        ),
        (
            "interlocks",
            "Interlocks per bench and month",
            "Runs that ended interlocked, by the month they began.",
            stops,
            lambda: interlock_figure(stops),
        ),
    ]
    out_dir.mkdir(parents=True, exist_ok=True)
    figures = []
    for name, title, caption, values, draw in drawn:
        if values:
            path = out_dir / f"{name}.png"
            draw().savefig(path, dpi=DPI)
            figures.append(FigureFile(name, title, caption, path))
    page = out_dir / TRENDS_PAGE
    page.write_text(
        _page(f"wfs-bench archive trends: {index_dir}", _sections(data, figures, points, freqs, stops)),
        encoding="utf-8",
    )
    return WrittenTrends(page, tuple(figures))


def _page(title: str, sections: list[tuple[str, str]]) -> str:
    """The page: self-contained like the report's, in its style."""
    body = "".join(f"<h2>{escape(heading)}</h2>{content}" for heading, content in sections)
    head = f'<meta charset="utf-8"><title>{escape(title)}</title><style>{PAGE_STYLE}</style>'
    page = f"<head>{head}</head><body><h1>{escape(title)}</h1>{body}</body>"
    return f'<!DOCTYPE html><html lang="en">{page}</html>\n'


def _sections(
    data: ds.Dataset,
    figures: list[FigureFile],
    points: list[TyrePoint],
    freqs: list[Eigenfrequency],
    stops: Counter,
) -> list[tuple[str, str]]:
    files = data.to_table(columns=["path", "file_status", "error"], filter=ds.field("entry") == c.FILE)
    statuses = Counter(files["file_status"].to_pylist())
    problems = files.filter(pc.invert(pc.is_null(files["error"])))
    summary = table_html(
        ("item", "value"),
        (
            *((f"files {status}", n) for status, n in sorted(statuses.items())),
            ("tyre identifications", len(points)),
            ("hammer tests", len(freqs)),
            ("runs ended interlocked", sum(stops.values())),
        ),
    )
    shown = (
        "".join(figure_html(f) for f in figures) or "<p>No figure: the index holds none of their values.</p>"
    )
    listed = table_html(
        ("file", "status", "error"), ((r["path"], r["file_status"], r["error"]) for r in problems.to_pylist())
    )
    return [
        ("Archive", summary),
        ("Figures", shown),
        ("Files not fully indexed", listed if problems.num_rows else "<p>None.</p>"),
    ]
