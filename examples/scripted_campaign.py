"""A campaign scripted in Python: the same steps a sequence file holds, built and run from code.

An engineer's script: the free run without the wheel, then a dwell grid at two pressures, each
pressure set by the operator (on the simulated bench, the simulated operator sets it), all recorded
into one campaign file and analysed after each run.

    python examples/scripted_campaign.py [OUT.h5]      (--help: usage)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bench.app.plan import plan_sequence
from bench.app.run import run_campaign
from bench.app.run_log import RunLog
from bench.config import default_bench_config
from sequences import DwellGrid, FreeRun, Hydraulics, Prompt, Sequence

TIMING = {"settle_cycles": 3, "settle_min_s": 0.2, "measure_cycles": 4, "measure_min_s": 0.5}
TAPERS = {"taper_in_s": 0.2, "taper_out_s": 0.2}


def scripted_sequence(pressures_bar: tuple[float, ...] = (1.5, 2.5)) -> Sequence:
    """Free run 5-80 Hz, then per pressure a prompt and a 2 mm grid around the tread resonance."""
    steps = [
        Hydraulics("low"),
        Prompt("remove_wheel", "Remove the wheel from the bench", action="remove_wheel"),
        Hydraulics("high"),
        FreeRun(DwellGrid(freqs_hz=(5.0, 20.0, 40.0, 80.0), amplitudes_mm=(2.0,), **TIMING, **TAPERS)),
        Hydraulics("low"),
        Prompt("fit_wheel", "Fit the wheel with the sensor", action="fit_wheel"),
    ]
    for pressure in pressures_bar:
        steps += [
            Hydraulics("low"),
            Prompt(
                f"pressure_{pressure:g}",
                f"Set the tyre pressure to {pressure:g} bar and enter the gauge reading",
                answer="number",
                unit="bar",
                minimum=0.5,
                maximum=4.5,
                action="set_tyre_pressure",
                target=pressure,
            ),
            Hydraulics("high"),
            DwellGrid(
                freqs_hz=(2.0, 10.0, 25.0, 30.0, 35.0, 40.0, 45.0, 60.0),
                amplitudes_mm=(2.0,),
                label=f"{pressure:g} bar",
                **TIMING,
                **TAPERS,
            ),
        ]
    steps.append(Hydraulics("off"))
    return Sequence(name="scripted", description="free run and two pressures", steps=tuple(steps))


def main(out: Path) -> int:
    plan = plan_sequence(scripted_sequence(), default_bench_config("shaker"))
    outcome = run_campaign(plan, out, subscribers=(RunLog(print),))
    print(f"{outcome.status}; campaign file {out}")
    return 0 if outcome.status == "complete" else 1


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line, as a command takes it: usage, --help, an unknown option refused."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "out", nargs="?", type=Path, default=Path("scripted-campaign.h5"), help="the campaign file to write"
    )
    return parser.parse_args(argv)


if __name__ == "__main__":
    sys.exit(main(parse_args().out))
