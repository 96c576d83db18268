"""Both jobs over many files, in one process against a local Dask cluster, in the same run:
``wfsbench compensate`` of ``--hours`` distinct one-hour road measurements (MDF4, 1 kHz) and
``wfsbench index`` of ``--campaigns`` distinct small campaign files; and each job again over its
unchanged folder, as a user runs it (the command in a fresh interpreter, ``--workers 2``).

The data is made once into ``--dir`` and kept: the paper's campaign at 2.5 bar with its analysis
stored beside its runs, as the bench stores it (:mod:`tests.campaign_files`), an hour of class C
road at 60 km/h on the paper's quarter car (simulated once) made into distinct hours (each its own
circular shift of the road and its own seeded sensor noise, :func:`distinct_hour`), and the
archive's campaigns (:mod:`tests.archive_files`).
Each measurement runs in a fresh process into a new output folder, so that every figure includes
the imports and none profits from another's warm caches:

- ``one process``: the baseline, every file read in the job's own process (``--workers 0``);
- ``dask``: the job as the command runs it with ``--workers``: a local ``dask.distributed`` cluster
  of that many processes of one thread each (:class:`bench.cluster.OnDask`: started while the job's
  first files are done in its own process, stopped at its end; all of it in the wall time); the
  peak memory (resident) of each worker, the processor time of the workers, of the process they are
  forked from and of the client (scheduler and nannies live in the client's process), the batches
  done in the client meanwhile;
- ``again``: the command over the folder just done: nothing changed, nothing read, no cluster.

Per file: processor time, wall time, bytes of input; docs/compensate.md and docs/index.md turn
them into the cost model. The machine is shared and its speed drifts by tens of percent over
minutes: the one-process run, the cluster's and ``plain`` (the files split between ``--workers``
plain processes run at once, no Dask: the machine's own capacity for the job) are repeated in turn
``--repeats`` times, each ratio is against the baseline measured just before it, and the medians of
the ratios are printed with each repeat's; the 1-minute load average is printed before and after.
Peak memory is each process's own high-water mark (``VmHWM``: ``ru_maxrss`` would carry the peak of
the process that started it across ``exec``).

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/fleet_jobs.py [--hours 40] [--campaigns 200] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bench import ONE_THREAD_VARIABLES

ROOT = Path(__file__).resolve().parents[1]
#: The measurements run as the commands do: on one thread of linear algebra. Importing ``bench``
#: sets it before numpy loads (``bench.ONE_THREAD_VARIABLES``); a measurement's process loads numpy
#: first (this module), so it gets the setting from its environment. A value the environment holds
#: is kept.
_ENV = {**dict.fromkeys(ONE_THREAD_VARIABLES, "1"), **os.environ, "PYTHONPATH": str(ROOT)}
HOUR_S = 3600.0
#: The campaign the measurements are compensated with, its analysis stored as the bench stores it.
CAMPAIGN = "campaign-analysed.h5"
#: The sensor noise each distinct hour adds on its shifted road (rms per sample): the campaign's level.
NOISE_N, NOISE_M_S2 = 1.0, 0.05


def _load() -> float:
    return float(Path("/proc/loadavg").read_text().split()[0])


def peak_memory_mb() -> float:
    """This process's peak resident memory (``VmHWM``), MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmHWM in /proc/self/status")


def forked_from_cpu_s(client) -> float:
    """The processor time of the processes this one started that are not the cluster's workers (the
    process the workers are forked from, multiprocessing's resource tracker), s."""
    import psutil

    workers = set(client.run(os.getpid).values())
    others = [child for child in psutil.Process().children(recursive=True) if child.pid not in workers]
    return sum(sum(child.cpu_times()[:2]) for child in others)


def distinct_hour(base: dict[str, np.ndarray], i: int) -> dict[str, np.ndarray]:
    """The ``i``-th distinct hour: the base hour shifted circularly by a seeded offset, with seeded
    white sensor noise of its own on each channel."""
    rng = np.random.default_rng(1000 + i)
    shift = int(rng.integers(base["fz_wfs_n"].size))
    return {
        "fz_wfs_n": np.roll(base["fz_wfs_n"], shift) + rng.normal(0, NOISE_N, base["fz_wfs_n"].size),
        "a_hub_m_s2": np.roll(base["a_hub_m_s2"], shift) + rng.normal(0, NOISE_M_S2, base["a_hub_m_s2"].size),
    }


def prepare(directory: Path, hours: int, campaigns: int) -> None:
    """The campaign, the hours and the archive in ``directory`` (what exists is kept)."""
    from tests.archive_files import write_archive
    from tests.campaign_files import paper_corner_runs, write_analysed_campaign
    from tests.fleet.roads import CAR, road_channels, write_mdf4

    directory.mkdir(parents=True, exist_ok=True)
    if not (directory / CAMPAIGN).exists():
        partial = write_analysed_campaign(directory / f"{CAMPAIGN}.partial", paper_corner_runs(CAR))
        partial.rename(directory / CAMPAIGN)
    roads = directory / "roads"
    roads.mkdir(exist_ok=True)
    todo = [i for i in range(hours) if not (roads / f"hour-{i:03d}.mf4").exists()]
    if todo:
        base_file = directory / "base-hour.npz"
        if not base_file.exists():
            np.savez(directory / "base-hour.partial.npz", **road_channels(99, duration_s=HOUR_S))
            (directory / "base-hour.partial.npz").rename(base_file)
        base = dict(np.load(base_file))
        for i in todo:
            partial = roads / f".hour-{i:03d}.partial.mf4"
            write_mdf4(partial, distinct_hour(base, i)).rename(roads / f"hour-{i:03d}.mf4")
    write_archive(directory / "archive", campaigns)


def _root(job: str, directory: Path) -> Path:
    """The folder a job reads: the hours or the archive."""
    return directory / ("roads" if job == "compensate" else "archive")


def shares(job: str, directory: Path, n: int) -> list[Path]:
    """``n`` folders of symbolic links that split the job's files between them, every ``n``-th file
    to each (made once, beside the data)."""
    files = sorted(f for f in _root(job, directory).iterdir() if f.suffix in (".mf4", ".h5"))
    files = [f for f in files if not f.name.startswith(".")]
    folders = [directory / "shares" / f"{job}-{n}" / str(i) for i in range(n)]
    for i, folder in enumerate(folders):
        if not folder.exists():
            partial = folder.with_name(folder.name + ".partial")
            shutil.rmtree(partial, ignore_errors=True)
            partial.mkdir(parents=True)
            for f in files[i::n]:
                (partial / f.name).symlink_to(f)
            partial.rename(folder)
    return folders


def _job(job: str, directory: Path, root: Path, out: Path, executor):
    if job == "compensate":
        from bench.fleet.job import compensate_many, identification
        from bench.fleet.worker import Settings

        settings = Settings(str(directory / CAMPAIGN), "", pressure_bar=2.5)
        settings = replace(settings, identification=identification(settings))
        summary = compensate_many([root], out, settings, executor)
        return summary.statuses
    from bench.archive.build import build_index

    return build_index([root], out, executor).statuses


def measure(job: str, mode: str, directory: Path, out: Path, *, workers: int, root: Path) -> dict:
    """One measurement in this (fresh) process, of the files under ``root``."""
    from bench.cluster import InProcess, OnDask

    start, cpu = time.perf_counter(), time.process_time()
    figures: dict = {}
    if mode == "dask":

        def look(client) -> None:
            """The workers' peak memory and processor time, before the cluster stops."""
            figures["workers_max_rss_mb"] = sorted(client.run(peak_memory_mb).values())
            figures["workers_cpu_s"] = sum(client.run(time.process_time).values())
            figures["forked_from_cpu_s"] = forked_from_cpu_s(client)

        executor = OnDask(None, workers, before_close=look)
        figures["statuses"] = _job(job, directory, root, out, executor)
        figures["done_here"] = executor.done_here
    else:
        figures["statuses"] = _job(job, directory, root, out, InProcess())
    return {
        **figures,
        "wall_s": time.perf_counter() - start,
        "cpu_s": time.process_time() - cpu,
        "max_rss_mb": peak_memory_mb(),
    }


def _command(job: str, mode: str, directory: Path, out: Path, *, workers: int, root: Path) -> list[str]:
    return [
        *(sys.executable, __file__, "--measure", job, mode, "--dir", str(directory), "--out", str(out)),
        *("--workers", str(workers), "--root", str(root)),
    ]


def run_fresh(job: str, mode: str, directory: Path, out: Path, workers: int) -> dict:
    command = _command(job, mode, directory, out, workers=workers, root=_root(job, directory))
    done = subprocess.run(command, capture_output=True, text=True, check=True, env=_ENV)
    return json.loads(done.stdout.splitlines()[-1])


def run_plain(job: str, directory: Path, out: Path, workers: int) -> dict:
    """The job's files split between ``workers`` plain processes (no Dask) run at once, each its
    share in one process: the machine's own capacity for the job. Wall s (the last to end) and the
    processes' processor s."""
    start = time.perf_counter()
    running = [
        subprocess.Popen(
            _command(job, "one", directory, out / str(i), workers=workers, root=share),
            stdout=subprocess.PIPE,
            env=_ENV,
        )
        for i, share in enumerate(shares(job, directory, workers))
    ]
    outputs = [process.communicate()[0] for process in running]
    wall_s = time.perf_counter() - start
    if any(process.returncode for process in running):
        raise RuntimeError(f"a plain process of the {job} failed")
    figures = [json.loads(output.splitlines()[-1]) for output in outputs]
    return {"wall_s": wall_s, "cpu_s": sum(figure["cpu_s"] for figure in figures)}


def run_again(job: str, directory: Path, out: Path, workers: int) -> float:
    """The command over the folder it has done, in a fresh interpreter, as a user runs it: wall s."""
    if job == "compensate":
        arguments = ["compensate", str(directory / CAMPAIGN), str(directory / "roads")]
        arguments += ["--pressure", "2.5"]
    else:
        arguments = ["index", str(directory / "archive")]
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "bench.cli", *arguments, "--out", str(out), "--workers", str(workers)],
        capture_output=True,
        check=True,
        env=_ENV,
    )
    return time.perf_counter() - start


def written_per_measurement(out: Path, n: int) -> str:
    """What the compensation wrote per measurement into ``out`` (the one-process run's folder): both
    outputs together, and each, in MB (the sizes do not depend on how many measurements were done)."""
    from bench.fleet.job import HDF5_SUFFIX, MDF4_SUFFIX

    hdf5, mdf4 = (
        sum(f.stat().st_size for f in out.rglob(f"*{suffix}")) / n / 1e6
        for suffix in (HDF5_SUFFIX, MDF4_SUFFIX)
    )
    return f"written {hdf5 + mdf4:.1f} MB: the HDF5 output {hdf5:.1f} MB, the MDF4 copy {mdf4:.1f} MB"


def report(
    job: str, files: list[Path], repeats: list[dict], *, again_s: float, workers: int, out: Path
) -> None:
    """Print a job's figures: each cluster run and each plain run against the one-process baseline
    measured just before them, the medians of those ratios, and the processor and memory figures of
    the repeat that gave the cluster's median (``out``: a baseline's output folder)."""
    n, size_bytes = len(files), sum(f.stat().st_size for f in files)
    what = f"{n} one-hour measurements" if job == "compensate" else f"{n} campaign files"
    print(f"\n{job}: {what}, {size_bytes / n / 1e6:.1f} MB each; outcomes {repeats[0]['one']['statuses']}")
    if job == "compensate":
        print(f"  per measurement: {written_per_measurement(out, n)}")
    ratios = [repeat["one"]["wall_s"] / repeat["dask"]["wall_s"] for repeat in repeats]
    plain = [repeat["one"]["wall_s"] / repeat["plain"]["wall_s"] for repeat in repeats]
    for i, (repeat, ratio) in enumerate(zip(repeats, ratios, strict=True), 1):
        print(
            f"  run {i}: one process {repeat['one']['wall_s']:.1f} s, local Dask cluster of {workers}"
            f" processes {repeat['dask']['wall_s']:.1f} s (its start and stop included): {ratio:.2f}x;"
            f" {workers} plain processes, each its share: {repeat['plain']['wall_s']:.1f} s,"
            f" {plain[i - 1]:.2f}x"
        )
    median = statistics.median(ratios)
    capacity = statistics.median(plain)
    print(f"  median of the {workers} plain processes: {capacity:.2f}x (the machine's capacity for the job)")
    middle = repeats[min(range(len(repeats)), key=lambda i: abs(ratios[i] - median))]
    one, dask = middle["one"], middle["dask"]
    print(f"  median of the cluster: {median:.2f}x the baseline's speed over {len(repeats)} repeats")
    print(
        f"  the median repeat: one process {one['cpu_s']:.1f} s processor, {one['cpu_s'] / n:.3f} s per file,"
        f" peak memory {one['max_rss_mb']:.0f} MB; the cluster's processor: workers"
        f" {dask['workers_cpu_s']:.1f} s,"
        f" the process they are forked from {dask['forked_from_cpu_s']:.1f} s, client {dask['cpu_s']:.1f} s"
        f" ({dask['done_here']} tasks done in it while the cluster started)"
    )
    print(f"  peak memory per worker: {', '.join(f'{m:.0f}' for m in dask['workers_max_rss_mb'])} MB")
    print(f"  again over the unchanged folder (the command, --workers {workers}): {again_s:.2f} s wall")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=int, default=40)
    parser.add_argument("--campaigns", type=int, default=200)
    parser.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()) / "wfsbench-fleet")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3, help="one-process and cluster runs alternated")
    parser.add_argument("--jobs", nargs="+", default=["compensate", "index"], choices=["compensate", "index"])
    parser.add_argument("--measure", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--root", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure(*args.measure, args.dir, args.out, workers=args.workers, root=args.root)))
        return
    made = time.perf_counter()
    prepare(args.dir, args.hours, args.campaigns)
    print(f"data in {args.dir} (made or found in {time.perf_counter() - made:.0f} s)")
    print(f"load (1 min) before: {_load():.2f}")
    work = Path(tempfile.mkdtemp(prefix="fleet-jobs-"))
    try:
        for job in args.jobs:
            files = sorted(_root(job, args.dir).iterdir())
            files = [f for f in files if f.suffix in (".mf4", ".h5") and not f.name.startswith(".")]
            repeats = []
            for i in range(args.repeats):
                one = run_fresh(job, "one", args.dir, work / f"{job}-one-{i}", args.workers)
                dask = run_fresh(job, "dask", args.dir, work / f"{job}-dask-{i}", args.workers)
                plain = run_plain(job, args.dir, work / f"{job}-plain-{i}", args.workers)
                repeats.append({"one": one, "dask": dask, "plain": plain})
            again_s = run_again(job, args.dir, work / f"{job}-one-0", args.workers)
            report(job, files, repeats, again_s=again_s, workers=args.workers, out=work / f"{job}-one-0")
    finally:
        shutil.rmtree(work)
    print(f"\nload (1 min) after: {_load():.2f}")


if __name__ == "__main__":
    main()
