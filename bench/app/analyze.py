"""Analysis of a whole campaign file, whatever wrote it, and its results stored beside the runs.

:func:`analyze_campaign` replays the complete runs of any file that follows the HDF5 schema
(docs/hdf5.md) in the order they began, through the same :class:`~bench.app.run_analysis.RunAnalyser`
the post-run analysis uses while a campaign runs: the hammer test gives the sensor, the free runs
the plate masses, each tyre pressure's dwell grids the tyre, the four-post sweep the car. The
sensor and wheel masses come from the bench configuration stored in the file (``config_toml``),
or the defaults when the file holds none.

:func:`store_reanalysis` writes what the analysis found beside the raw data under new result names
(``<name>-reanalysis-<n>``, ``n`` one more than any earlier re-analysis of the file): the raw data
and every earlier result stay as they were.

The file is opened before the estimators are loaded: a missing or foreign file is refused without
the cost of importing the analysis (``benchmarks/cli_startup.py``).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from bench.config import BenchConfig, ConfigError, default_bench_config, parse_bench_config
from bench.engine.run_ids import RUN_ID
from bench.store import add_results, open_campaign
from sequences.runs import RigKind, RunKind, RunStatus

if TYPE_CHECKING:
    from bench.analysis.campaign import CampaignAnalysis, CampaignKnowledge, RunAnalysis

#: How re-analysis results are named: ``<analysis name>-reanalysis-<n>``.
REANALYSIS_NAME = re.compile(r"^(?P<name>.+)-reanalysis-(?P<n>[0-9]+)$")


class CampaignFileError(ValueError):
    """The file is no campaign file, or its contents cannot be analysed; the message names the
    file and what is wrong."""


def stored_config(path: Path, config_toml: str, name: str) -> tuple[BenchConfig, str]:
    """The bench configuration a campaign file stored, and where it came from (its name,
    ``"stored"``, or ``"defaults"`` when the file holds none); :class:`CampaignFileError` when the
    stored text is no valid configuration."""
    if not config_toml.strip():
        return default_bench_config(), "defaults"
    try:
        return parse_bench_config(config_toml, f"{path}@config_toml", base_dir=path.parent), name or "stored"
    except ConfigError as err:
        raise CampaignFileError(f"{path}: the stored bench configuration is invalid: {err}") from err


def sequences_run(run_ids: Iterable[str]) -> tuple[tuple[str, int], ...]:
    """The sequences of a campaign file's runs, as (name, number of runs) in the order they first
    ran. The file keeps only the first sequence's name and text (``/@sequence_name``); a sequence
    appended later leaves its name in its run ids (``shaker-s002-free_run``). A run id of another
    form counts as its own name."""
    counts: dict[str, int] = {}
    for run_id in run_ids:
        match = RUN_ID.match(run_id)
        name = match["sequence"] if match else run_id
        counts[name] = counts.get(name, 0) + 1
    return tuple(counts.items())


def analyze_campaign(
    path: str | Path,
    config: BenchConfig | None = None,
    knowledge: CampaignKnowledge | None = None,
    *,
    reanalyse: bool = False,
    keep_records: bool = False,
) -> CampaignAnalysis:
    """The analysis of every complete run of the campaign file at ``path``, in order: the one the
    post-run analysis stored beside each run (:mod:`bench.app.analysis_record`), read back without
    fitting anything; or, when ``reanalyse`` is asked, a run has no record this version reads, or
    ``config`` replaces the configuration stored in the file (its masses), the runs analysed again
    (:attr:`CampaignAnalysis.source` says which, and why). ``knowledge``: what the analysis of this
    file's runs has established already (the post-run analysis of the campaign that wrote it, in
    memory): the runs it took in are not analysed again. Not both: the knowledge holds its masses. A
    file that does not follow the schema raises :class:`~bench.store.StoreError` (which names the
    file and the place); an analysis that fails for one run is a flagged :class:`RunAnalysis`, not
    an error. ``keep_records``: the runs fitted here keep their records
    (:attr:`CampaignAnalysis.records`, for a caller that stores them); made only when asked, as
    laying an analysis out as JSON costs a fraction of a second a campaign."""
    path = Path(path)
    if config is not None and knowledge is not None:
        raise ValueError("give a configuration or a knowledge, not both: the knowledge holds its masses")
    with open_campaign(path) as campaign:
        from bench.analysis.campaign import CampaignAnalysis
        from bench.app.analysis_record import StoredAnalysis, analyse_and_record, stored_analysis
        from bench.app.run_analysis import (
            RunAnalyser,
            RunInputs,
            initial_knowledge,
            replay_campaign,
            runs_to_analyse,
        )

        if config is None:
            config, source = stored_config(path, campaign.config_toml, campaign.config_name)
            given = False
        else:
            source, given = config.source, True
        stored: StoredAnalysis | str
        records: dict[str, str] = {}  # the records of the runs analysed here
        if knowledge is not None:
            stored = ""
        elif given:
            stored = "the bench configuration given replaces the stored one"
        elif reanalyse:
            stored = "asked (--reanalyse)"
        else:
            stored = stored_analysis(runs_to_analyse(campaign), initial_knowledge(config))
        if isinstance(stored, StoredAnalysis):
            knowledge, runs = stored.knowledge, stored.runs
            how = f"as stored after each run by wfs-bench {', '.join(stored.software_versions)}"
        else:
            how = f"analysed again: {stored}" if stored else "as made while the campaign ran"
            analyser = RunAnalyser(knowledge or initial_knowledge(config))
            knowledge = analyser.knowledge

            def analyse(run: RunInputs) -> RunAnalysis:
                outcome, _, records[run.run_id] = analyse_and_record(analyser, run)
                return outcome

            runs = tuple(replay_campaign(campaign, analyser, analyse if keep_records else None))
        masses = config.masses
        hammer = next(
            (run for run in campaign.runs if run.kind == RunKind.HAMMER and run.status == RunStatus.COMPLETE),
            None,
        )
        four_post = [  # the last is the one the knowledge's four-post result comes from
            run
            for run in campaign.runs
            if run.kind == RunKind.SWEEP
            and run.status == RunStatus.COMPLETE
            and run.conditions.get("bench") == RigKind.FOUR_POST
        ]
        return CampaignAnalysis(
            path=path,
            software_version=campaign.software_version,
            sequence_name=campaign.sequence_name,
            config_source=source,
            sensor_mass_kg=masses.sensor_kg,
            wheel_mass_kg=masses.wheel_below_sensor_kg,
            knowledge=knowledge,
            runs=runs,
            skipped=tuple((run.run_id, run.status) for run in campaign.runs if run.status != "complete"),
            hammer_record=hammer.hammer_record() if hammer is not None else None,
            sequences=sequences_run(run.run_id for run in campaign.runs),
            sweep_record=four_post[-1].sweep_record() if four_post and knowledge.four_post else None,
            metadata=dict(campaign.metadata),
            run_pressures_bar={
                run.run_id: float(pressure)
                for run in campaign.runs
                if (pressure := run.conditions.get("tyre_pressure_bar")) is not None
            },
            source=how,
            stored=isinstance(stored, StoredAnalysis),
            records=records,
        )


def next_reanalysis(path: str | Path) -> int:
    """The number of the next re-analysis of the campaign file at ``path`` (1 for the first)."""
    with open_campaign(path) as campaign:
        numbers = [
            int(match["n"])
            for run in campaign.runs
            for name in run.result_names
            if (match := REANALYSIS_NAME.match(name))
        ]
    return max(numbers, default=0) + 1


def store_reanalysis(analysis: CampaignAnalysis) -> dict[str, str]:
    """Write each analysed run's results beside it under a new name; returns run id -> the name.
    The stored result is the one the post-run analysis stores: the text summary and the scalar
    results; a run without an analysis record (a file written before they were kept, or by another
    writer) gets this analysis's, so that the file is fitted once."""
    n = next_reanalysis(analysis.path)
    names = {run.run_id: f"{run.name}-reanalysis-{n}" for run in analysis.runs}
    add_results(
        analysis.path,
        {
            (run.run_id, names[run.run_id]): {"summary": "\n".join(run.lines), **run.results}
            for run in analysis.runs
        },
        analysis.records,
    )
    return names
