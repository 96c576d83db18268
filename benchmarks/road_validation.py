"""The compensation validated on simulated roads: ISO 8608 classes B and C at 30, 60 and 100 km/h on
the simulated quarter car (the paper's corner: its tyre at 2.5 bar, Model 2, non-linear),
compensated with what a campaign of that corner identified, as ``wfsbench compensate`` does.

Per case: the rms error of the raw, hub-acceleration-compensated and model-compensated force
against the true contact force in 0-30 Hz and per octave; the share of samples whose true force lies
inside the 95 % band (both forces limited to the valid band, and unfiltered); the median half-width.
The same road is also read by sensors other than the bench's (``other_sensors``: a hub accelerometer
of twice the lag, a WFS three times as noisy), compensated with that lag stated (the noise estimated
from the measurement) and without (0 assumed): the share inside the band in the valid band. And the
same road driven by the car with a linear tyre (the campaign's tyre without its stiffness rise and
friction, as an independent quarter car would model it): the share inside the band in the valid band.
The figures (like the paper's Figure 1) go to ``--figures`` (docs/figures by default).

    PYTHONPATH=. .venv/bin/python benchmarks/road_validation.py [--campaign FILE]

Without ``--campaign`` the campaign is the paper's procedure for that corner simulated directly
(``tests/campaign_files.py``: the shaker's free run, the 2.5 bar grids at 1 / 2 / 5 mm, the post's
free run and the four-post sweep, seeded, analysed as the bench stores its analysis), made first into
a temporary folder: every run prints the same figures. (The demo's campaign, ``--campaign``, runs on
the simulated bench in real time: its fits, and so the figures, differ a little from run to run.)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from bench.analysis.road_validation import OCTAVE_CENTRES_HZ, RoadValidation
from bench.app.analyze import analyze_campaign
from bench.models.benches import TyreModel
from bench.models.road import road_drive
from bench.models.setup import BenchSetup
from bench.report.road_figures import road_compensation_figure
from bench.simulated_road import other_sensors, validate_on_road
from bench.store.measurement_chain import MeasurementChain, Stated
from benchmarks.documented import Documented

#: A seeded campaign (the default): every run prints the same figures.
DOCUMENTED = Documented(
    arguments=("--figures", "{tmp}"),  # not over the documents' own figures
    tables_in="docs/compensate.md",
    quoted={
        "summary (README.md): ": "README.md",
        "model-compensated error: ": "docs/compensate.md",
        "valid band and tyre: ": "docs/compensate.md",
        "a linear tyre: ": "docs/compensate.md",
        "a lag not stated, class C at 60 km/h: ": "docs/compensate.md",
    },
)
CASES = (("B", 30.0), ("B", 60.0), ("B", 100.0), ("C", 30.0), ("C", 60.0), ("C", 100.0))
#: The cases drawn.
FIGURE_CASES = (("C", 60.0), ("B", 100.0))
PRESSURE_BAR = 2.5
CAR = BenchSetup.paper_quarter_car(PRESSURE_BAR, model=TyreModel.WHEEL_TREAD)
#: The same car with a linear tyre: a road tyre without the rate and amplitude dependence the
#: campaign's tyre has.
LINEAR_CAR = BenchSetup.paper_quarter_car(PRESSURE_BAR, model=TyreModel.WHEEL_TREAD, nonlinear=False)


def _campaign(given: str | None, folder: Path) -> Path:
    if given:
        return Path(given)
    from tests.campaign_files import paper_corner_runs, write_analysed_campaign

    start = time.perf_counter()
    path = write_analysed_campaign(folder / "campaign.h5", paper_corner_runs(CAR))
    print(f"the corner's campaign simulated and analysed in {time.perf_counter() - start:.0f} s", flush=True)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--campaign", help="a campaign file with the 2.5 bar tyre (default: the corner's, simulated)"
    )
    parser.add_argument("--figures", default="docs/figures", help="folder for the PNG figures")
    parser.add_argument("--duration", type=float, default=20.0, help="seconds of road per case")
    parser.add_argument("--seed", type=int, default=5, help="road seed (the sensors' noise: seed + 2)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        analysis = analyze_campaign(_campaign(args.campaign, Path(tmp)))
    figures = Path(args.figures)
    figures.mkdir(parents=True, exist_ok=True)
    results, others, linear = [], [], []
    for road_class, speed in CASES:
        drive = road_drive(
            road_class, speed_km_h=speed, duration_s=args.duration, sample_rate_hz=1000.0, seed=args.seed
        )
        same = {"pressure_bar": PRESSURE_BAR, "seed": args.seed + 2}
        result = validate_on_road(analysis, CAR, drive, **same)
        results.append(result)
        others.append(_other_sensors(analysis, drive, args.seed + 4))
        linear.append(validate_on_road(analysis, LINEAR_CAR, drive, **same))
        if (road_class, speed) in FIGURE_CASES:
            path = figures / f"road-compensation-{road_class.lower()}-{speed:.0f}kmh.png"
            road_compensation_figure(result).savefig(path)
            print(f"figure {path}")
    for r in results:
        band = f"{r.valid_band_hz[0]:.3g}-{r.valid_band_hz[1]:.3g} Hz"
        print(f"{r.road_class} {r.speed_km_h:.0f} km/h compensated with the {r.identification}, valid {band}")
    print(
        "\n| road | true force rms | raw | hub-acceleration | model-compensated | model / raw"
        " | inside the 95 % band, in the valid band | unfiltered | median half-width"
        " | other sensors, stated: inside, in the valid band | a linear tyre: inside, in the valid band |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r, (stated, _), lin in zip(results, others, linear, strict=True):
        print(
            f"| {r.road_class} {r.speed_km_h:.0f} km/h | {r.truth_rms_n:.0f} N | {r.raw.rms_n:.1f} N"
            f" | {r.hub_compensated.rms_n:.1f} N | {r.model_compensated.rms_n:.2f} N"
            f" | {r.model_compensated.rms_n / r.raw.rms_n:.4f} | {100 * r.coverage_valid_band:.1f} %"
            f" | {100 * r.coverage_whole:.1f} % | {r.median_u95_n:.2f} N"
            f" | {100 * stated.coverage_valid_band:.1f} % | {100 * lin.coverage_valid_band:.1f} % |"
        )
    print(
        "\nthe same roads read by other sensors (a hub accelerometer of twice the bench's lag, a WFS three"
        " times as noisy)\n\n| road | the chain | lag undone | Fz noise in the band | model-compensated"
        " | inside the 95 % band, in the valid band | median half-width |\n|---|---|---|---|---|---|---|"
    )
    for r, pair in zip(results, others, strict=True):
        for what, o in zip(("lag stated", "nothing stated"), pair, strict=True):
            print(
                f"| {r.road_class} {r.speed_km_h:.0f} km/h | {what} | {o.hub_lag_ms:.3g} ms"
                f" | {o.noise_wfs_n:.2f} N | {o.model_compensated.rms_n:.2f} N"
                f" | {100 * o.coverage_valid_band:.1f} % | {o.median_u95_n:.2f} N |"
            )
    print(f"\nsummary (README.md): {_summary(results, [stated for stated, _ in others], linear)}")
    shares = [r.model_compensated.rms_n / r.truth_rms_n for r in results]
    print(f"model-compensated error: {100 * min(shares):.2f}-{100 * max(shares):.2f} % of the true rms")
    print(f"valid band and tyre: {_bands_and_amplitudes(results)}")
    half_widths = [r.median_u95_n for r in results]
    print(
        f"a linear tyre: inside the band in at least {100 * min(r.coverage_valid_band for r in linear):.1f} %"
        f" of the samples; the median half-width on the bench's own roads ({min(half_widths):.2f}-"
        f"{max(half_widths):.2f} N)"
    )
    stated_c60, unstated = others[CASES.index(("C", 60.0))]
    print(
        f"a lag not stated, class C at 60 km/h: {unstated.model_compensated.rms_n:.1f} N rms error in 0-30 Hz"
        f" and {100 * unstated.coverage_valid_band:.1f} % of the samples in the band with 0 assumed,"
        f" {stated_c60.model_compensated.rms_n:.2f} N and {100 * stated_c60.coverage_valid_band:.1f} %"
        " with the lag stated"
    )
    print("\nthe band's Fz noise on the bench's own roads")
    for r in results:
        noise = next(line for line in r.assumptions if "Fz noise" in line)
        print(f"{r.road_class} {r.speed_km_h:.0f} km/h: {noise}")
    octaves = " | ".join(f"{c:g} Hz" for c in OCTAVE_CENTRES_HZ)
    print(f"\nper octave (rms error, N)\n\n| road | force | {octaves} |")
    print("|---|---|" + "---|" * len(OCTAVE_CENTRES_HZ))
    for r in results:
        for name, errors in (("raw", r.raw), ("hub", r.hub_compensated), ("model", r.model_compensated)):
            cells = " | ".join(f"{e:.3g}" for e in errors.octave_rms_n)
            print(f"| {r.road_class} {r.speed_km_h:.0f} km/h | {name} | {cells} |")
    return 0


def _bands_and_amplitudes(results: list[RoadValidation]) -> str:
    """The valid band(s) and which tyre amplitude each road's compensation chose, as the document
    says them: ``0.61-29.2 Hz; 1 mm (B at 30 and 60 km/h), 2 mm (...)``."""
    bands = sorted({f"{r.valid_band_hz[0]:.3g}-{r.valid_band_hz[1]:.3g} Hz" for r in results})
    by_amplitude: dict[str, dict[str, list[str]]] = {}
    for r in results:
        amplitude = r.identification.split(", ")[-1].split(" (")[0]
        by_amplitude.setdefault(amplitude, {}).setdefault(r.road_class, []).append(f"{r.speed_km_h:.0f}")
    parts = []
    for amplitude, roads in sorted(by_amplitude.items(), key=lambda item: float(item[0].split()[0])):
        speeds = [f"{c} at {' and '.join(v)}" for c, v in roads.items()]
        parts.append(f"{amplitude} ({', '.join(speeds)} km/h)")
    return f"{', '.join(bands)}; {', '.join(parts)}"


def _summary(
    results: list[RoadValidation], stated: list[RoadValidation], linear: list[RoadValidation]
) -> str:
    """The README's line: each figure's range over the roads."""

    def span(values, form: str, scale: float = 1.0) -> str:
        low, high = (form.format(scale * v) for v in (min(values), max(values)))
        return f"{low}-{high}"  # always a range: a collapsed one would read as other words

    def inside(rows: list[RoadValidation]) -> str:
        return span([r.coverage_valid_band for r in rows], "{:.1f}", 100) + " %"

    return (
        f"model-compensated error {span([r.model_compensated.rms_n for r in results], '{:.2f}')} N rms"
        f" in 0-30 Hz (raw {span([r.raw.rms_n for r in results], '{:.0f}')} N, hub acceleration"
        f" {span([r.hub_compensated.rms_n for r in results], '{:.0f}')} N); true force inside the 95 %"
        f" band in {inside(results)} of the samples within the valid band; the same roads read by another"
        f" accelerometer (twice the lag) and a WFS three times as noisy, the lag stated: {inside(stated)};"
        f" driven on a linear tyre: {inside(linear)}"
    )


def _other_sensors(analysis, drive, seed: int) -> tuple[RoadValidation, RoadValidation]:
    """The road read by :func:`other_sensors`, compensated with their accelerometer's lag stated,
    and with nothing stated (0 assumed)."""
    sensors = other_sensors(seed)
    stated = MeasurementChain(
        hub_lag_ms=Stated(1e3 * sensors.accelerometer_lag_s, "the road's accelerometer")
    )
    common = {"pressure_bar": PRESSURE_BAR, "seed": seed, "sensors": sensors}
    return (
        validate_on_road(analysis, CAR, drive, chain=stated, **common),
        validate_on_road(analysis, CAR, drive, chain=MeasurementChain(), **common),
    )


if __name__ == "__main__":
    sys.exit(main())
