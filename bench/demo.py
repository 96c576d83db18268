"""``wfsbench demo``: the paper's whole campaign run through the engine on the simulated bench.

The same path a lab's campaign takes: the shipped sequence files, validated and dry-run against the
simulated benches' configurations; the controller over Modbus TCP on 127.0.0.1 and the WFS over a
pseudo-terminal; every frame recorded to ``DIR/campaign.h5``; the prompts (remove the wheel, set
the pressure, put the car on the posts, strike the hammer) answered by the simulated operator, who
applies each answer to the simulated world; the analysis after each run.

1. Hammer test of the bare sensor: its eigenfrequency and damping give the sensor model.
2. Shaker: the free run without a wheel (m_comp), then dwell grids at 1 / 2 / 5 mm for each of
   1.5 / 2.5 / 3.5 bar: Models 1-3 identified per amplitude, the model-based compensator, and the
   valid band of the raw and the compensated WFS force.
3. Four-post sweep of one corner at 2.5 bar, with the post's own free run: m_wheel, the quarter car,
   and the valid band raw / hub-acceleration compensated / model compensated.
4. The report of the whole file (``wfsbench report``): figures and one HTML page in ``DIR/report/``.

The simulated plant has sensor noise, quantisation, a servo-hydraulic actuator and the non-linear
tyre; the analysis sees only what the bench recorded.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping
from pathlib import Path

from bench.analysis.campaign import CampaignKnowledge
from bench.app.library_log import library_log, log_beside
from bench.app.plan import plan_sequence
from bench.app.report import write_report
from bench.app.run import run_campaign
from bench.app.run_analysis import initial_knowledge
from bench.config import default_bench_config
from bench.models.benches import TyreModel
from bench.models.parameters import PAPER_TYRE_STIFFNESS_N_PER_M, Tyre
from bench.report.text import summary_lines
from bench.store import open_campaign
from sequences import load_sequence, shipped_file
from sequences.runs import RigKind

#: The demo's sequences, in the paper's order, each with the kind of bench it runs on.
DEMO_SEQUENCES = (
    ("hammer.toml", RigKind.SHAKER),
    ("paper_shaker.toml", RigKind.SHAKER),
    ("paper_four_post.toml", RigKind.FOUR_POST),
)


def _band(band) -> str:
    return f"{band.upper_hz:5.1f} Hz" if band.determined else "not determined"


def run_demo(out_dir: Path, seed: int = 1, metadata: Mapping[str, str] | None = None) -> list[str]:
    """Run the campaign into ``out_dir/campaign.h5`` (a previous demo file there is replaced),
    write its report (figures and ``report.html``) to ``out_dir/report/``; return the summary's
    lines, the last of which names the report page. ``metadata``: test metadata fields recorded
    with the campaign and its every run (``--meta``)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / "campaign.h5"
    out.unlink(missing_ok=True)
    log_beside(out).unlink(missing_ok=True)
    knowledge: CampaignKnowledge | None = None
    start = time.perf_counter()
    with library_log(log_beside(out)) as log:  # the links' warnings: to a file, not the screen
        for name, kind in DEMO_SEQUENCES:
            config = default_bench_config(kind)
            config = dataclasses.replace(config, simulation=dataclasses.replace(config.simulation, seed=seed))
            path = shipped_file(name)
            sequence = load_sequence(path, config.limits)
            plan = plan_sequence(sequence, config, path.read_text(), config.to_toml())
            plan = plan.with_metadata(metadata or {})
            if knowledge is None:
                knowledge = initial_knowledge(config)
            outcome = run_campaign(plan, out, knowledge=knowledge)
            if outcome.status != "complete":
                raise RuntimeError(f"demo sequence {name} ended {outcome.status}: {outcome.reason}")
    wall_s = time.perf_counter() - start
    lines = _report(knowledge, out, wall_s)
    written = write_report(out, out_dir / "report", knowledge=knowledge)
    warned = [f"warnings of the links and libraries: {log.path}"] if log.written else []
    return [*lines, *warned, "", f"report ({len(written.figures)} figures): {written.page}"]


def _recorded_s(path: Path) -> float:
    """Sample time recorded in the campaign file (s)."""
    with open_campaign(path) as campaign:
        return sum(run.n_samples / run.sample_rate_hz for run in campaign.runs)


def _report(k: CampaignKnowledge, out: Path, wall_s: float) -> list[str]:
    recorded_s = _recorded_s(out)
    lines = [
        "wfs-bench demo: the paper's campaign through the engine on the simulated bench"
        " (Modbus TCP, WFS on a pty; noise, quantisation, servo-hydraulic actuator, non-linear tyre)",
        f"recorded {recorded_s:.0f} s of samples in {wall_s:.1f} s ({recorded_s / wall_s:.0f}x real time)"
        f" to {out}",
        "",
    ]
    if k.hammer is not None:
        lines += [*summary_lines(k.hammer), ""]
    lines += [
        "shaker bench, Model 2 per amplitude (k at its reference frequency, 10 Hz; max over the dwells):",
        f"{'pressure':>8} {'amplitude':>9} {'k kN/m':>8} {'m_T kg':>7} {'d Ns/m':>7}"
        f" {'max |F_WFS/F_c|':>16} {'raw band':>9} {'compensated':>12}",
    ]
    for pressure, result in sorted(k.shaker.items()):
        for amplitude_m, r in result.amplitudes.items():
            tyre: Tyre = r.identification.fits[TyreModel.WHEEL_TREAD].tyre
            lines.append(
                f"{pressure:>6.1f} bar {1e3 * amplitude_m:>6.0f} mm {tyre.stiffness_n_per_m / 1e3:>8.1f}"
                f" {tyre.tread_mass_kg:>7.2f} {tyre.damping_ns_per_m:>7.1f}"
                f" {max(abs(r.frfs.wfs_per_contact.value)):>16.1f} {_band(r.valid_band_raw):>9}"
                f" {_band(r.valid_band_compensated):>12}"
            )
    truth = ", ".join(
        f"{p:g} bar {k_n / 1e3:.0f} kN/m" for p, k_n in sorted(PAPER_TYRE_STIFFNESS_N_PER_M.items())
    )
    lines.append(f"(simulator's nominal tyres: {truth}; m_T 6 kg; viscous d 80 Ns/m plus rubber friction)")
    if 2.5 in k.shaker:
        lines += ["", "2.5 bar in full:", *summary_lines(k.shaker[2.5])]
    if k.four_post is not None:
        lines += ["", *summary_lines(k.four_post)]
    return lines
