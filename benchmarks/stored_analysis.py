"""The analysis read from its records against the same analysis fitted again (``--reanalyse``).

The campaign file is the demo's (the paper's whole campaign: hammer test, shaker free run and 9 dwell
grids, four-post free run and sweep), made first with ``wfsbench demo`` unless ``--campaign`` names
one (not timed); its runs carry the records the post-run analysis stored. Timed, each the best of
``--repeats``, as a user runs them (a fresh ``wfsbench`` process each, its start included):
``analyze --json --no-store`` and ``report --out DIR``, from the records and with ``--reanalyse``.
Then ``index --workers 0`` of ``--files`` copies of the file (each made distinct by its ``notes``,
as the index reads a file of known contents only once), from the records and with ``--reanalyse``:
seconds per file. Ratios: the refit's time over the stored read's.

Run: ``OMP_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python benchmarks/stored_analysis.py [--campaign FILE]``
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py

from benchmarks.report_speed import campaign_or_demo
from benchmarks.timing import run_benchmark


def wfsbench_s(*args: str) -> float:
    """Wall time of one ``wfsbench ARGS`` process (s); a failing command stops the benchmark."""
    script = Path(sys.executable).with_name("wfsbench")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bench.cli"]
    start = time.perf_counter()
    done = subprocess.run([*command, *args], capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"wfsbench {' '.join(args)} failed ({done.returncode}): {done.stderr}")
    return elapsed


def best_s(repeats: int, *args: str) -> float:
    return min(wfsbench_s(*args) for _ in range(repeats))


def distinct_copies(campaign: Path, folder: Path, n: int) -> None:
    """``n`` copies of ``campaign`` in ``folder``, each with its own ``notes`` (distinct contents)."""
    folder.mkdir()
    for i in range(n):
        copy = folder / f"campaign-{i:03d}.h5"
        shutil.copyfile(campaign, copy)
        with h5py.File(copy, "r+") as f:
            f.attrs["notes"] = f"copy {i}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaign", type=Path, help="campaign file (default: made with the demo)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--files", type=int, default=20, help="copies the index reads")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        campaign = str(campaign_or_demo(args.campaign, work))
        rows = []
        for name, command in (
            ("analyze --json", ("analyze", campaign, "--json", "--no-store")),
            ("report", ("report", campaign, "--out", str(work / "report"))),
        ):
            stored = best_s(args.repeats, *command)
            refit = best_s(args.repeats, *command, "--reanalyse")
            rows.append((name, stored, refit))
        distinct_copies(Path(campaign), work / "files", args.files)
        per_file = []
        for tag, extra in (("stored", ()), ("refit", ("--reanalyse",))):
            out = str(work / f"index-{tag}")
            per_file.append(wfsbench_s("index", str(work / "files"), "--out", out, "--workers", "0", *extra))
        print(f"campaign: {campaign} ({Path(campaign).stat().st_size / 1e6:.1f} MB)")
        print("| command | from the records (s) | --reanalyse (s) | refit / stored |")
        print("|---|---|---|---|")
        for name, stored, refit in rows:
            print(f"| {name} | {stored:.2f} | {refit:.2f} | {refit / stored:.1f}x |")
        stored, refit = (t / args.files for t in per_file)
        print(f"| index, per file of {args.files} | {stored:.2f} | {refit:.2f} | {refit / stored:.1f}x |")


if __name__ == "__main__":
    run_benchmark(main)
