"""Where a local Dask cluster's time goes against plain processes, for ``wfsbench index``: the
measurement behind docs/index.md, *Why two workers gave 0.98x*.

The same ``--files`` campaign files (the archive of ``benchmarks/fleet_jobs.py``, made there or
here) are indexed, each configuration in a fresh process:

- ``one process``: every file in this process, one after another (the baseline);
- ``two processes``: ``--workers`` plain processes, each its share (the machine's capacity);
- a local cluster of ``--workers`` one-thread processes as ``dask.distributed`` makes it by default,
  and with each suspect taken away in turn: the workers' statistical profiler (a thread that samples
  the task's stack every 10 ms), the ``MALLOC_TRIM_THRESHOLD_`` its nannies set in each worker's
  environment (it also fixes glibc's mmap threshold: every large array is mapped and unmapped), and
  the two together (what :func:`bench.cluster.dask_client` now starts).

Per configuration: the wall time of the whole (cluster start and stop timed apart), the processor
time per file of the task itself (the thread that runs it), of the worker processes as a whole (the
task and every other thread of the worker: event loop, profiler, heartbeats), minor page faults per
file, and the client process's processor time (it holds the scheduler and the nannies); the bytes
of the results sent back per file (their serialisation). Thread counts of a worker are printed (the
BLAS pools a worker starts). Each configuration is repeated ``--repeats`` times in turn with the
others and its shortest repeat kept; the 1-minute load is printed before and after.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/dask_overhead.py [--files 40] [--repeats 2]``
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import pickle
import resource
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
#: Configurations of the local cluster: name -> the dask settings changed from Dask's defaults.
CLUSTERS = {
    "dask, as it comes": {},
    "dask, no profiler": {"distributed.worker.profile.enabled": False},
    "dask, no MALLOC_TRIM_THRESHOLD_": {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None},
    "dask, neither (bench.cluster)": "bench.cluster",
}


def _load() -> float:
    return float(Path("/proc/loadavg").read_text().split()[0])


def index_timed(paths: list[str]) -> dict:
    """Index ``paths`` here; the processor time of this thread, the minor page faults of this
    process, the wall time and the bytes of the outcomes pickled."""
    from bench.archive.build import FileTask, index_file
    from bench.archive.files import FileStat

    start, cpu, process_cpu = time.perf_counter(), time.thread_time(), time.process_time()
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    outcomes = [index_file(FileTask(p, FileStat.of(p))) for p in paths]
    return {
        "files": len(paths),
        "task_cpu_s": time.thread_time() - cpu,
        "process_cpu_s": time.process_time() - process_cpu,
        "wall_s": time.perf_counter() - start,
        "faults": resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults,
        "result_bytes": len(pickle.dumps(outcomes)),
    }


def _worker_state() -> dict:
    return {
        "cpu_s": time.process_time(),
        "threads": threading.active_count(),
        "native_threads": len(os.listdir("/proc/self/task")),
        "faults": resource.getrusage(resource.RUSAGE_SELF).ru_minflt,
    }


def measure_cluster(name: str, paths: list[str], workers: int) -> dict:
    """One configuration of the local cluster, in this fresh process."""
    import dask
    from dask.distributed import LocalCluster

    from bench.cluster import dask_client

    start = time.perf_counter()
    settings = CLUSTERS[name]
    if settings == "bench.cluster":
        context = dask_client(None, workers)
    else:
        with dask.config.set(settings):
            cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
        context = _closing(cluster)
    with context as client:
        started = time.perf_counter()
        before = client.run(_worker_state)
        cpu = time.process_time()
        futures = [client.submit(index_timed, paths[i::workers], pure=False) for i in range(workers)]
        results = [f.result() for f in futures]
        ran = time.perf_counter()
        client_cpu = time.process_time() - cpu
        after = client.run(_worker_state)
        stopping = time.perf_counter()
    n = len(paths)
    return {
        "start_s": started - start,
        "run_s": ran - started,
        "stop_s": time.perf_counter() - stopping,
        "wall_s": time.perf_counter() - start,
        "task_cpu_per_file_s": sum(r["task_cpu_s"] for r in results) / n,
        "worker_cpu_per_file_s": sum(after[w]["cpu_s"] - before[w]["cpu_s"] for w in after) / n,
        "faults_per_file": sum(after[w]["faults"] - before[w]["faults"] for w in after) / n,
        "client_cpu_per_file_s": client_cpu / n,
        "result_bytes_per_file": sum(r["result_bytes"] for r in results) / n,
        "worker_threads": sorted(s["native_threads"] for s in after.values()),
    }


@contextlib.contextmanager
def _closing(cluster) -> Iterator:
    """A client of the local ``cluster``; both closed on leaving."""
    from dask.distributed import Client

    with cluster, Client(cluster) as client:
        yield client


def measure_plain(paths: list[str]) -> dict:
    start = time.perf_counter()
    result = index_timed(paths)
    n = len(paths)
    return {
        "wall_s": time.perf_counter() - start,
        "task_cpu_per_file_s": result["task_cpu_s"] / n,
        "process_cpu_per_file_s": result["process_cpu_s"] / n,
        "faults_per_file": result["faults"] / n,
        "native_threads": len(os.listdir("/proc/self/task")),
    }


def _fresh(arguments: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, __file__, *arguments], stdout=subprocess.PIPE, text=True, env=_ENV
    )


def _result(process: subprocess.Popen) -> dict:
    out = process.communicate()[0]
    if process.returncode:
        raise RuntimeError(f"a measurement failed ({process.returncode})")
    return json.loads(out.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=40)
    parser.add_argument(
        "--dir", type=Path, default=Path(tempfile.gettempdir()) / "wfsbench-fleet" / "archive"
    )
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--plain", nargs="*", help=argparse.SUPPRESS)
    parser.add_argument("--cluster", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.plain is not None:
        print(json.dumps(measure_plain(args.plain)))
        return
    from tests.archive_files import write_archive

    paths = [str(p) for p in write_archive(args.dir, args.files)]
    if args.cluster:
        print(json.dumps(measure_cluster(args.cluster, paths, args.workers)))
        return
    print(f"{args.files} campaign files of {args.dir}; load (1 min) before: {_load():.2f}")
    best: dict[str, dict] = {}
    for _ in range(args.repeats):
        runs = {"one process": _result(_fresh(["--plain", *paths]))}
        start = time.perf_counter()
        shares = [_fresh(["--plain", *paths[i :: args.workers]]) for i in range(args.workers)]
        split = [_result(p) for p in shares]
        runs["plain processes"] = {
            "wall_s": max(s["wall_s"] for s in split),
            "task_cpu_per_file_s": sum(
                s["task_cpu_per_file_s"] * len(paths[i :: args.workers]) for i, s in enumerate(split)
            )
            / len(paths),
            "faults_per_file": sum(s["faults_per_file"] for s in split) / len(split),
            "elapsed_s": time.perf_counter() - start,
        }
        for name in CLUSTERS:
            runs[name] = _result(
                _fresh(["--cluster", name, "--files", str(args.files), "--dir", str(args.dir)])
            )
        for name, figures in runs.items():
            if name not in best or figures["wall_s"] < best[name]["wall_s"]:
                best[name] = figures
    report(best, args.workers)
    print(f"load (1 min) after: {_load():.2f}")


def report(best: dict[str, dict], workers: int) -> None:
    base = best["one process"]
    print(
        f"one process: {base['wall_s']:.1f} s; {1e3 * base['task_cpu_per_file_s']:.0f} ms processor per file"
        f" on its main thread, {1e3 * base['process_cpu_per_file_s']:.0f} ms with its other threads (BLAS),"
        f" {base['faults_per_file']:.0f} minor page faults per file; {base['native_threads']} threads"
    )
    split = best["plain processes"]
    print(
        f"{workers} plain processes, each its share: {split['wall_s']:.1f} s,"
        f" {base['wall_s'] / split['wall_s']:.2f}x; {1e3 * split['task_cpu_per_file_s']:.0f} ms per file"
    )
    for name in CLUSTERS:
        d = best[name]
        print(
            f"{name}: {d['wall_s']:.1f} s wall (start {d['start_s']:.1f}, run {d['run_s']:.1f}, stop"
            f" {d['stop_s']:.1f}): {base['wall_s'] / d['wall_s']:.2f}x, the run alone"
            f" {base['wall_s'] / d['run_s']:.2f}x; per file: task {1e3 * d['task_cpu_per_file_s']:.0f} ms,"
            f" worker process {1e3 * d['worker_cpu_per_file_s']:.0f} ms, client"
            f" {1e3 * d['client_cpu_per_file_s']:.0f} ms, {d['faults_per_file']:.0f} page faults,"
            f" {d['result_bytes_per_file'] / 1e3:.1f} kB of results; worker threads {d['worker_threads']}"
        )


if __name__ == "__main__":
    main()
