"""How long ``wfsbench`` takes to start, as a user runs it, against a bare Python interpreter.

Each command runs in a fresh interpreter (``python -m bench.cli ...``, what the ``wfsbench``
console script does), interleaved with the baseline, a bare ``python -c pass``, in the same run:
``--runs`` rounds, each round running every command once, in turn. Per command: the median and the
shortest wall time, and how much they lie above the baseline's (difference and ratio). Target
(issue 18): ``wfsbench --help`` and ``wfsbench analyze`` on a missing file at most 0.3 s above the
bare interpreter.

``--compare DIR`` times the same commands of another copy of the repository (its root ``DIR``,
for instance ``mkdir /tmp/before && git archive main | tar -x -C /tmp/before``) in the same rounds
and with the same interpreter, so that a change is measured before and after under the same load.

    PYTHONPATH=. .venv/bin/python benchmarks/cli_startup.py [--runs 15] [--compare DIR]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The bare interpreter every figure is compared with.
BARE = ("bare python -c pass", ("-c", "pass"))
#: (what, the arguments of ``python``); the analysed file never exists.
COMMANDS = (
    ("wfsbench --help", ("-m", "bench.cli", "--help")),
    ("wfsbench analyze MISSING.h5", ("-m", "bench.cli", "analyze", "missing-campaign-file.h5")),
    ("wfsbench check smoke.toml", ("-m", "bench.cli", "check", "sequences/files/smoke.toml")),
)
#: Commands the target is set for, and the target (s above the bare interpreter, median).
TARGET_COMMANDS = ("wfsbench --help", "wfsbench analyze MISSING.h5")
TARGET_S = 0.3


def wall_time_s(args: tuple[str, ...], root: Path) -> float:
    """Wall time of ``python ARGS`` run in ``root`` (s); its output is discarded, any exit code taken."""
    start = time.perf_counter()
    subprocess.run([sys.executable, *args], cwd=root, capture_output=True, check=False)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=15, help="rounds; every command runs once per round")
    parser.add_argument("--compare", type=Path, metavar="DIR", help="also time the checkout at DIR")
    args = parser.parse_args()
    roots = {"": ROOT} | ({" (compared)": args.compare.resolve()} if args.compare else {})
    timed = [(*BARE, ROOT)]
    timed += [(f"{what}{tag}", argv, root) for tag, root in roots.items() for what, argv in COMMANDS]
    times: dict[str, list[float]] = {what: [] for what, _, _ in timed}
    for _ in range(args.runs):
        for what, argv, root in timed:
            times[what].append(wall_time_s(argv, root))
    bare_median, bare_min = statistics.median(times[BARE[0]]), min(times[BARE[0]])
    print(f"{sys.executable}, {args.runs} runs each, interleaved; checkout {ROOT}")
    print(f"{BARE[0]:40} median {bare_median * 1e3:6.0f} ms  min {bare_min * 1e3:6.0f} ms")
    for what, _, _ in timed[1:]:
        median, shortest = statistics.median(times[what]), min(times[what])
        above = median - bare_median
        target = ""
        if what in TARGET_COMMANDS:
            met = "met" if above <= TARGET_S else "NOT met"
            target = f"  (target <= {TARGET_S * 1e3:.0f} ms above: {met})"
        print(
            f"{what:40} median {median * 1e3:6.0f} ms  min {shortest * 1e3:6.0f} ms;"
            f" above bare: median +{above * 1e3:.0f} ms ({median / bare_median:.1f}x),"
            f" min +{(shortest - bare_min) * 1e3:.0f} ms ({shortest / bare_min:.1f}x){target}"
        )


if __name__ == "__main__":
    main()
