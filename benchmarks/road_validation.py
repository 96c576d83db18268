"""The compensation validated on simulated roads: ISO 8608 classes B and C at 30, 60 and 100 km/h on
the simulated quarter car (the demo's four-post corner: the paper's tyre at 2.5 bar, Model 2,
non-linear), compensated with what the demo campaign identified, as ``wfsbench compensate`` does.

Per case: the rms error of the raw, hub-acceleration-compensated and model-compensated force
against the true contact force in 0-30 Hz and per octave; the share of samples whose true force lies
inside the 95 % band (both forces limited to the valid band, and unfiltered); the median half-width.
The figures (like the paper's Figure 1) go to ``--figures`` (docs/figures by default).

    PYTHONPATH=. .venv/bin/python benchmarks/road_validation.py [--campaign FILE]

Without ``--campaign`` the demo campaign is run first into a temporary folder (about a minute).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from bench.analysis.road_validation import OCTAVE_CENTRES_HZ
from bench.app.analyze import analyze_campaign
from bench.models.benches import TyreModel
from bench.models.road import road_drive
from bench.models.setup import BenchSetup
from bench.report.road_figures import road_compensation_figure
from bench.simulated_road import validate_on_road

CASES = (("B", 30.0), ("B", 60.0), ("B", 100.0), ("C", 30.0), ("C", 60.0), ("C", 100.0))
#: The cases drawn.
FIGURE_CASES = (("C", 60.0), ("B", 100.0))
PRESSURE_BAR = 2.5
CAR = BenchSetup.paper_quarter_car(PRESSURE_BAR, model=TyreModel.WHEEL_TREAD)


def _campaign(given: str | None, folder: Path) -> Path:
    if given:
        return Path(given)
    from bench.demo import run_demo

    start = time.perf_counter()
    run_demo(folder, seed=1)
    print(f"demo campaign run in {time.perf_counter() - start:.0f} s", flush=True)
    return folder / "campaign.h5"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaign", help="a campaign file with the 2.5 bar tyre (default: run the demo)")
    parser.add_argument("--figures", default="docs/figures", help="folder for the PNG figures")
    parser.add_argument("--duration", type=float, default=20.0, help="seconds of road per case")
    parser.add_argument("--seed", type=int, default=5, help="road seed (the sensors' noise: seed + 2)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        analysis = analyze_campaign(_campaign(args.campaign, Path(tmp)))
    figures = Path(args.figures)
    figures.mkdir(parents=True, exist_ok=True)
    results = []
    for road_class, speed in CASES:
        drive = road_drive(
            road_class, speed_km_h=speed, duration_s=args.duration, sample_rate_hz=1000.0, seed=args.seed
        )
        result = validate_on_road(analysis, CAR, drive, pressure_bar=PRESSURE_BAR, seed=args.seed + 2)
        results.append(result)
        if (road_class, speed) in FIGURE_CASES:
            path = figures / f"road-compensation-{road_class.lower()}-{speed:.0f}kmh.png"
            road_compensation_figure(result).savefig(path)
            print(f"figure {path}")
    for r in results:
        band = f"{r.valid_band_hz[0]:.3g}-{r.valid_band_hz[1]:.3g} Hz"
        print(f"{r.road_class} {r.speed_km_h:.0f} km/h compensated with the {r.identification}, valid {band}")
    print(
        "\n| road | true force rms | raw | hub-acceleration | model-compensated | model / raw"
        " | inside the 95 % band, in the valid band | unfiltered | median half-width |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in results:
        print(
            f"| {r.road_class} {r.speed_km_h:.0f} km/h | {r.truth_rms_n:.0f} N | {r.raw.rms_n:.1f} N"
            f" | {r.hub_compensated.rms_n:.1f} N | {r.model_compensated.rms_n:.2f} N"
            f" | {r.model_compensated.rms_n / r.raw.rms_n:.4f} | {100 * r.coverage_valid_band:.1f} %"
            f" | {100 * r.coverage_whole:.1f} % | {r.median_u95_n:.2f} N |"
        )
    octaves = " | ".join(f"{c:g} Hz" for c in OCTAVE_CENTRES_HZ)
    print(f"\nper octave (rms error, N)\n\n| road | force | {octaves} |")
    print("|---|---|" + "---|" * len(OCTAVE_CENTRES_HZ))
    for r in results:
        for name, errors in (("raw", r.raw), ("hub", r.hub_compensated), ("model", r.model_compensated)):
            cells = " | ".join(f"{e:.3g}" for e in errors.octave_rms_n)
            print(f"| {r.road_class} {r.speed_km_h:.0f} km/h | {name} | {cells} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
