"""Time and size of ``wfsbench export`` of the demo campaign in each format.

The campaign file is the demo's (hammer test, shaker free run and 9 dwell grids, four-post free run
and sweep); it is made first with ``wfsbench demo`` unless ``--campaign`` names one (not timed).
Timed, each the best of ``--repeats``, in this process (imports paid before): the export of every run
in each format, as ``wfsbench export`` does it (``bench.cli.export.export``; UFF 58 includes the
analysis of the whole file, which gives its FRFs). Baseline in the same run: reading every channel of
every run with h5py (``read_every_channel``). Sizes against the campaign file's (HDF5, gzip level 1).

Run: ``OMP_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python benchmarks/export_speed.py [--campaign FILE]``
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from bench.cli.export import FORMATS, export
from benchmarks.report_speed import campaign_or_demo, read_every_channel
from benchmarks.timing import best_time_s


def size_bytes(path: Path) -> int:
    """A file's size, or the sum of a folder's files."""
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def timed_export(campaign: Path, fmt: str, out: Path, repeats: int) -> tuple[float, int]:
    """Best wall time of exporting ``campaign`` as ``fmt`` to ``out`` (removed between repeats, not
    timed) and the output's size."""
    best = float("inf")
    for _ in range(repeats):
        if out.is_dir():
            shutil.rmtree(out)
        out.unlink(missing_ok=True)
        start = time.perf_counter()
        export(campaign, fmt, out, None)
        best = min(best, time.perf_counter() - start)
    return best, size_bytes(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaign", type=Path, help="campaign file (default: made with the demo)")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        campaign = campaign_or_demo(args.campaign, work)
        import asammdf  # noqa: F401 - the writers' imports are not what is measured
        import pyuff  # noqa: F401

        samples = read_every_channel(campaign)
        t_base = best_time_s(lambda: read_every_channel(campaign), args.repeats)
        size = campaign.stat().st_size
        mb = 1e6
        print(f"campaign file: {size / mb:.1f} MB, {samples / 1e6:.2f} M samples")
        print(f"baseline, read every channel with h5py: {t_base:.2f} s")
        print(f"{'format':8} {'time (s)':>9} {'x baseline':>11} {'size (MB)':>10} {'x campaign file':>16}")
        for fmt in FORMATS:
            t, n = timed_export(campaign, fmt, work / f"out.{fmt}", args.repeats)
            print(f"{fmt:8} {t:9.2f} {t / t_base:11.1f} {n / mb:10.2f} {n / size:16.2f}")


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"(benchmark wall time {time.perf_counter() - start:.0f} s)")
