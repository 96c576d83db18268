"""The campaign index of a small archive (``wfsbench index``): one process against the local Dask
cluster on the machine's cores, the re-index of the unchanged archive, and the peak memory.

The archive is ``--files`` small campaign files made by the simulated bench
(:mod:`tests.archive_files`: a hammer test, a free run of 3 dwells and a grid of 9 dwells at 2 mm,
about 350 kB each), made once into ``--dir`` and kept. Each measurement is a fresh process that
indexes into a new index directory, so that every figure includes the imports and none profits
from another's warm caches in the process (the files are in the page cache for all: local disk):

- ``in_process``: the baseline, every file read in the command's own process (``--workers 0``);
- ``dask``: a ``dask.distributed`` local cluster of ``--workers`` processes (its start and stop
  timed apart), the index built on it;
- ``split``: the machine's own parallel capacity, without Dask: ``--workers`` plain processes
  started together, each indexing its share in itself (the cores may be busy with other work);
- ``reindex``: the same archive again into the index just built: nothing changed, nothing read;
- memory: the peak resident memory of the indexing process (and of the Dask workers), for the
  first ``--small`` files and for all of them: it must not grow with the number of files.

Each measurement is repeated ``--repeats`` times, in turn with the others, and its least disturbed
(shortest) repeat kept: the machine is shared. Per file: the wall and processor time, the bytes read
from the file system (``rchar`` of ``/proc/self/io``: the hash's pass over the file, then HDF5's
reads), the rows and Parquet bytes written. docs/index.md turns them into the cost model.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/archive_index.py [--files 200] [--dir DIR]``
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _rchar() -> int:
    with open("/proc/self/io") as io:
        return next(int(line.split()[1]) for line in io if line.startswith("rchar:"))


def measure(mode: str, archive: Path, files: int, out: Path, workers: int, *, first: int = 0) -> dict:
    """One measurement in this (fresh) process: index ``files`` files of ``archive`` from the
    ``first``."""
    from bench.archive.build import build_index
    from bench.cluster import InProcess, OnDask, dask_client

    roots = sorted(archive.glob("campaign-*.h5"))[first : first + files]
    start, cpu, rchar = time.perf_counter(), time.process_time(), _rchar()
    figures: dict = {}
    if mode == "dask":
        with dask_client(None, workers) as client:
            started = time.perf_counter()
            summary = build_index(roots, out, OnDask(client=client))
            figures["index_s"] = time.perf_counter() - started
            figures["workers_max_rss_mb"] = [
                rss / 1024
                for rss in client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss).values()
            ]
            figures["workers_cpu_s"] = sum(client.run(time.process_time).values())
            stopping = time.perf_counter()
        figures["cluster_stop_s"] = time.perf_counter() - stopping
        figures["cluster_start_s"] = started - start
    else:
        summary = build_index(roots, out, InProcess())
        figures["index_s"] = time.perf_counter() - start
    parquet = sum(p.stat().st_size for p in out.glob("part-*.parquet"))
    return {
        **figures,
        "wall_s": time.perf_counter() - start,
        "cpu_s": time.process_time() - cpu,
        "read_bytes": _rchar() - rchar,
        "files": files,
        "file_bytes": sum(p.stat().st_size for p in roots),
        "opened": sum(summary.statuses.values()),
        "unchanged": summary.unchanged,
        "rows": summary.rows_written,
        "parquet_bytes": parquet,
        "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def _command(mode: str, archive: Path, files: int, out: Path, workers: int, *, first: int = 0) -> list[str]:
    """The command line of :func:`measure` in a new Python process."""
    command = [sys.executable, __file__, "--measure", mode, "--dir", str(archive), "--files", str(files)]
    return [*command, "--first", str(first), "--out", str(out), "--workers", str(workers)]


_ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def run_fresh(mode: str, archive: Path, files: int, out: Path, workers: int) -> dict:
    """:func:`measure` in a new Python process."""
    done = subprocess.run(
        _command(mode, archive, files, out, workers), capture_output=True, text=True, check=True, env=_ENV
    )
    return json.loads(done.stdout.splitlines()[-1])


def run_split(archive: Path, files: int, out: Path, workers: int) -> dict:
    """The machine's own parallel capacity, without Dask: ``workers`` plain processes started
    together, each indexing its share of the archive in itself; the wall time of the slowest
    (inside it, like every other figure: the interpreter's start is not counted)."""
    share = -(-files // workers)
    commands = [
        _command("in_process", archive, share, out / str(n), workers, first=n * share) for n in range(workers)
    ]
    running = [subprocess.Popen(c, stdout=subprocess.PIPE, text=True, env=_ENV) for c in commands]
    results = [json.loads(p.communicate()[0].splitlines()[-1]) for p in running]
    return {"wall_s": max(r["wall_s"] for r in results), "cpu_s": sum(r["cpu_s"] for r in results)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=200)
    parser.add_argument("--small", type=int, default=50, help="the smaller archive of the memory figure")
    parser.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()) / "wfsbench-archive")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument(
        "--repeats", type=int, default=2, help="each figure the best (least disturbed) of these"
    )
    parser.add_argument("--measure", choices=("in_process", "dask"), help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--first", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(
            json.dumps(measure(args.measure, args.dir, args.files, args.out, args.workers, first=args.first))
        )
        return

    from tests.archive_files import write_archive

    made = time.perf_counter()
    write_archive(args.dir, args.files)
    print(f"archive: {args.files} files in {args.dir} (made or found in {time.perf_counter() - made:.1f} s)")
    work = Path(tempfile.mkdtemp(prefix="archive-index-"))
    plan = (  # name, mode, files, index directory (the re-index: into the baseline's)
        ("in_process", "in_process", args.files, "in_process"),
        ("dask", "dask", args.files, "dask"),
        ("reindex", "in_process", args.files, "in_process"),
        ("small", "in_process", args.small, "small"),
        ("small_dask", "dask", args.small, "small_dask"),
    )
    runs: dict[str, dict] = {}
    try:
        for repeat in range(args.repeats):  # in turn, so that a burst of load on the machine hits one repeat
            done = {
                name: run_fresh(mode, args.dir, n, work / f"{out}-{repeat}", args.workers)
                for name, mode, n, out in plan
            }
            done["split"] = run_split(args.dir, args.files, work / f"split-{repeat}", args.workers)
            for name, figures in done.items():
                if name not in runs or figures["wall_s"] < runs[name]["wall_s"]:
                    runs[name] = figures
    finally:
        shutil.rmtree(work)
    report(runs, args.workers)


def report(runs: dict[str, dict], workers: int) -> None:
    """Print the figures, each against the one-process baseline measured in the same run."""
    base, dask, again = runs["in_process"], runs["dask"], runs["reindex"]
    small, small_dask = runs["small"], runs["small_dask"]
    n = base["files"]
    print(
        f"one process (baseline): {n} files in {base['wall_s']:.1f} s wall, {base['cpu_s']:.1f} s processor;"
        f" {base['wall_s'] / n * 1e3:.0f} ms wall per file"
    )
    start, stop = dask["cluster_start_s"], dask["cluster_stop_s"]
    phases = f"start {start:.1f} s, index {dask['index_s']:.1f} s, stop {stop:.1f} s"
    print(
        f"local Dask cluster, {workers} processes: {dask['wall_s']:.1f} s wall ({phases});"
        f" {base['wall_s'] / dask['wall_s']:.2f}x the baseline's speed, the index alone"
        f" {base['wall_s'] / dask['index_s']:.2f}x; workers' processor {dask['workers_cpu_s']:.1f} s"
    )
    split = runs["split"]
    print(
        f"{workers} plain processes, each its share, no Dask: {split['wall_s']:.1f} s wall,"
        f" {base['wall_s'] / split['wall_s']:.2f}x the baseline's speed (what the machine's cores give now);"
        f" the Dask cluster {split['wall_s'] / dask['wall_s']:.2f}x their speed, the index alone"
        f" {split['wall_s'] / dask['index_s']:.2f}x"
    )
    print(
        f"re-index of the unchanged archive: {again['wall_s']:.2f} s, {again['opened']} files read,"
        f" {again['unchanged']} unchanged: {again['wall_s'] / base['wall_s'] * 100:.1f} % of the first index"
    )
    size, read = base["file_bytes"], base["read_bytes"]
    print(
        f"per file: {size / n / 1e3:.0f} kB, {read / n / 1e3:.0f} kB read ({read / size:.2f}x its size),"
        f" {base['cpu_s'] / n * 1e3:.0f} ms processor, {base['rows'] / n:.0f} rows,"
        f" {base['parquet_bytes'] / n:.0f} bytes of Parquet; re-index {again['wall_s'] / n * 1e3:.2f} ms"
    )
    for name, few, many in (("one process", small, base), ("Dask client", small_dask, dask)):
        print(
            f"peak memory, {name}: {few['max_rss_mb']:.0f} MB for {few['files']} files,"
            f" {many['max_rss_mb']:.0f} MB for {n} ({many['max_rss_mb'] / few['max_rss_mb']:.2f}x)"
        )
    workers_mb = [", ".join(f"{m:.0f}" for m in r["workers_max_rss_mb"]) for r in (small_dask, dask)]
    print(
        f"peak memory, Dask workers: {workers_mb[0]} MB for {small_dask['files']} files,"
        f" {workers_mb[1]} MB for {n}"
    )


if __name__ == "__main__":
    main()
