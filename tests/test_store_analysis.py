"""The analysis takes its records from a campaign file: simulated plant runs stored through the
writer and read back give the same analysis results as the records they were written from (the
channels are stored as float32, so the reference is the float32-rounded record), and the results
stored under the run read back as written."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bench.analysis import analyse_free_run, analyse_hammer
from bench.analysis.campaign import CampaignKnowledge
from bench.analysis.records import DwellRecord
from bench.app.analyze import analyze_campaign
from bench.app.run_analysis import RunAnalyser, replay_campaign
from bench.config import default_bench_config
from bench.models.parameters import WfsSensor
from bench.models.setup import BenchSetup
from bench.simulated_campaign import FREE_RUN_GRID_HZ, simulate_dwells, simulate_hammer
from bench.store import CampaignWriter, open_campaign
from sequences.channels import Channel
from sequences.points import PointAttempt

SENSOR_MASS_KG = 3.82


def _float32(record):
    return replace(record, channels={k: np.asarray(v, np.float32) for k, v in record.channels.items()})


def _store_dwells(run, records: list[DwellRecord]) -> None:
    """Each dwell's samples, block by block, then its point row."""
    for index, record in enumerate(records):
        start = run.samples
        n = len(record.channels["z_base_m"])
        for i in range(0, n, 100):
            run.append({name: record.channels[name][i : i + 100] for name in ("z_base_m", "f_plate_n")})
        hold_start, hold_end = (start + round(t * record.sample_rate_hz) for t in record.hold_s)
        run.add_point(
            PointAttempt(
                index, record.freq_hz, 1e3 * record.amplitude_m, start, hold_start, hold_end, start + n
            )
        )


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    free_run = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, 2e-3, seed=5)
    hammer = simulate_hammer(seed=6)
    path = tmp_path_factory.mktemp("analysis") / "campaign.h5"
    with CampaignWriter.create(
        path, software_version="test", config_toml="", sequence_toml="", sequence_name="free run and hammer"
    ) as writer:
        run = writer.begin_run(
            "001-free-run",
            kind="free_run",
            step={"type": "free_run"},
            conditions={"wheel_fitted": False},
            channels=(Channel("z_base_m", "m"), Channel("f_plate_n", "N")),
            sample_rate_hz=free_run[0].sample_rate_hz,
        )
        _store_dwells(run, free_run)
        run.finish("complete")
        run.write_results("free_run", {"m_comp_kg": analyse_free_run(free_run).plate.mass_kg})
        run = writer.begin_run(
            "002-hammer",
            kind="hammer",
            step={"type": "hammer"},
            conditions={},
            channels=tuple(Channel(name, "N") for name in hammer.channels),
            sample_rate_hz=hammer.sample_rate_hz,
        )
        run.append(hammer.channels)
        run.add_point(PointAttempt(0, math.nan, math.nan, 0, 0, run.samples, run.samples))
        run.finish("complete")
    return path, free_run, hammer


def test_free_run_from_the_file_gives_the_records_m_comp(stored):
    path, free_run, _ = stored
    with open_campaign(path) as campaign:
        run = campaign.run("001-free-run")
        from_file = analyse_free_run(run.dwell_records())
        written = run.results("free_run")["m_comp_kg"]
    reference = analyse_free_run([_float32(r) for r in free_run])
    assert from_file.plate.mass_kg == pytest.approx(reference.plate.mass_kg, rel=1e-12)
    # float32 storage against the float64 records: far inside m_comp's own uncertainty
    assert abs(from_file.plate.mass_kg - written) < 0.01 * from_file.plate.sigma_kg


def test_hammer_from_the_file_gives_the_records_eigenfrequency(stored):
    path, _, hammer = stored
    with open_campaign(path) as campaign:
        from_file = analyse_hammer(campaign.run("002-hammer").hammer_record(), sensor_mass_kg=SENSOR_MASS_KG)
    reference = analyse_hammer(_float32(hammer), sensor_mass_kg=SENSOR_MASS_KG)
    assert from_file.eigenfrequency_hz == pytest.approx(reference.eigenfrequency_hz, rel=1e-12)
    assert from_file.stiffness_n_per_m == pytest.approx(reference.stiffness_n_per_m, rel=1e-12)


def test_a_replay_analyses_the_runs_its_knowledge_has_not_taken_in_yet(stored):
    """A campaign's knowledge carried to its next sequence is not rebuilt from the file: the runs
    it took in give the analyses it holds, not analysed again; a fresh knowledge takes in every
    complete run."""
    path, _, _ = stored
    fresh = CampaignKnowledge(sensor=WfsSensor(mass_kg=SENSOR_MASS_KG), wheel_mass_kg=29.0)
    analyser = RunAnalyser(fresh)
    calls: list[str] = []
    analyse = analyser.analyse
    analyser.analyse = lambda run: calls.append(run.run_id) or analyse(run)
    with open_campaign(path) as campaign:
        first = replay_campaign(campaign, analyser)
        again = replay_campaign(campaign, analyser)
    assert [a.run_id for a in first] == ["001-free-run", "002-hammer"]
    assert [a.name for a in first] == ["plate_mass", "hammer"]
    assert list(fresh.analysed_runs) == ["001-free-run", "002-hammer"] and fresh.hammer is not None
    assert calls == ["001-free-run", "002-hammer"]  # the second replay analysed nothing again
    assert again == first and all(a is b for a, b in zip(again, first, strict=True))


def test_an_analysis_with_the_campaigns_knowledge_equals_a_fresh_one_without_analysing_again(stored):
    """The demo's report takes the knowledge its campaign's post-run analysis built: the file's
    analysis is then the fresh one, run for run, and no run is analysed twice."""
    path, _, _ = stored
    fresh = analyze_campaign(path)
    carried = CampaignKnowledge(sensor=fresh.knowledge.sensor, wheel_mass_kg=fresh.knowledge.wheel_mass_kg)
    with open_campaign(path) as campaign:
        replay_campaign(campaign, RunAnalyser(carried))  # as the post-run analysis did while it ran
    taken_in = dict(carried.analysed_runs)
    reused = analyze_campaign(path, knowledge=carried)
    assert [(r.run_id, r.lines, r.results.keys()) for r in reused.runs] == [
        (r.run_id, r.lines, r.results.keys()) for r in fresh.runs
    ]
    assert all(r is taken_in[r.run_id] for r in reused.runs)
    assert reused.knowledge is carried and reused.hammer_record is not None


def test_an_analysis_refuses_a_configuration_beside_a_knowledge(stored):
    path, _, _ = stored
    knowledge = CampaignKnowledge(sensor=WfsSensor(mass_kg=SENSOR_MASS_KG), wheel_mass_kg=29.0)
    with pytest.raises(ValueError, match="not both"):
        analyze_campaign(path, default_bench_config(), knowledge=knowledge)
