"""The post-run analysis kept as a record (docs/hdf5.md, *The analysis record*): a campaign recorded
on the simulated bench is analysed once, while it runs; ``analyze``, ``report``, ``export --format
uff58``, ``compensate`` and ``index`` read what it stored and fit nothing, and give what a new fit
(``--reanalyse``) gives to the last digit. A file without records is fitted again and says why; a
record that cannot be read is refused whole, naming its place, and the run is fitted again."""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pyarrow.parquet as pq
import pytest

from bench.analysis.campaign import CampaignKnowledge, RunAnalysis
from bench.app.analysis_record import RECORD_FORMAT, inputs_sha256, parse_record
from bench.app.analyze import analyze_campaign
from bench.app.run_analysis import RunAnalyser, run_inputs, runs_to_analyse
from bench.cli.exit_codes import ExitCode
from bench.models.benches import TyreModel
from bench.store import open_campaign
from bench.store.typed import TypedFormatError, from_json_tree, to_json_tree
from tests.commands import wfsbench
from tests.test_campaign_cli import H5DUMP

GRID_RUN = "smoke-s009-dwell_grid"
#: index columns that say when and by what it ran, not what it found
INDEX_TIMES = ("indexed_at", "indexed_by")


@pytest.fixture
def fits(monkeypatch) -> list[str]:
    """The runs the analysis fits in this process, counted as :meth:`RunAnalyser.analyse` is called."""
    calls: list[str] = []
    analyse = RunAnalyser.analyse

    def counted(self, run):
        calls.append(run.run_id)
        return analyse(self, run)

    monkeypatch.setattr(RunAnalyser, "analyse", counted)
    return calls


@pytest.fixture
def recorded(smoke_campaign, tmp_path) -> Path:
    """A copy of the smoke campaign, whose runs the post-run analysis recorded as they ran."""
    return Path(shutil.copyfile(smoke_campaign, tmp_path / "smoke.h5"))


def assert_same(a: object, b: object, where: str = "") -> None:
    """``a`` and ``b`` equal to the last digit, field by field (arrays of the same type and shape)."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for field in dataclasses.fields(a):
            if field.init:
                assert_same(getattr(a, field.name), getattr(b, field.name), f"{where}.{field.name}")
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), where
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, list | tuple):
        assert type(a) is type(b) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and (a.dtype, a.shape) == (b.dtype, b.shape), where
        assert np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"), where
    else:
        both_nan = isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b)
        assert a == b or both_nan, f"{where}: {a!r} != {b!r}"


def test_every_run_of_a_recorded_campaign_has_its_record(recorded):
    """Each analysed run's record: this format, this software, the SHA-256 of the inputs read back."""
    with open_campaign(recorded) as campaign:
        runs = runs_to_analyse(campaign)
        records = [parse_record(run.analysis_record) for run in runs]
        digests = [inputs_sha256(run_inputs(run, campaign)) for run in runs]
    assert [r.outcome.run_id for r in records] == [run.run_id for run in runs]
    assert [r.order for r in records] == list(range(len(runs)))
    assert [r.inputs_sha256 for r in records] == digests
    assert [r.outcome.name for r in records] == ["plate_mass", "shaker", "sweep"]
    assert set(records[1].changes) >= {"shaker", "analysed_runs"}


@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_h5dump_reads_a_record_as_json_text(recorded):
    where = f"/runs/{GRID_RUN}/analysis"
    dump = subprocess.run([H5DUMP, "-d", where, str(recorded)], capture_output=True, text=True, check=True)
    text = dump.stdout.split('(0): "', 1)[1]
    assert "DATATYPE  H5T_STRING" in dump.stdout and text.startswith(f'{{"format":{RECORD_FORMAT},')


def test_the_stored_analysis_is_the_fit_to_the_last_digit_without_fitting(recorded, fits):
    stored = analyze_campaign(recorded)
    assert fits == [] and stored.stored
    assert stored.source.startswith("as stored after each run by wfs-bench ")
    again = analyze_campaign(recorded, reanalyse=True)
    assert fits == [run.run_id for run in again.runs] and not again.stored
    assert again.source == "analysed again: asked (--reanalyse)"
    assert_same(stored.knowledge, dataclasses.replace(again.knowledge, shaker_free_run=[]), "knowledge")
    assert_same(stored.runs, again.runs, "runs")


@pytest.mark.slow
def test_the_commands_read_the_record_and_give_what_a_refit_gives(recorded, tmp_path, fits):
    """analyze --json, report, export --format uff58, compensate and index: nothing fitted; the same
    output as with --reanalyse (which fits every run), byte for byte or value for value."""

    def outputs(tag: str, *reanalyse: str) -> dict[str, object]:
        out = tmp_path / tag
        out.mkdir()
        analysis = wfsbench("analyze", str(recorded), "--json", "--no-store", *reanalyse)
        report = wfsbench("report", str(recorded), "--out", str(out / "report"), *reanalyse)
        uff = wfsbench("export", str(recorded), "--format", "uff58", "--out", str(out / "f.uff"), *reanalyse)
        measured = (str(recorded), "--run", GRID_RUN)
        compensated = wfsbench("compensate", str(recorded), *measured, "--out", str(out / "c.h5"), *reanalyse)
        index = wfsbench("index", str(recorded), "--out", str(out / "index"), "--workers", "0", *reanalyse)
        for done in (analysis, report, uff, compensated, index):
            assert done.returncode == ExitCode.OK, done.stdout + done.stderr
        doc = json.loads(analysis.stdout)
        source = doc.pop("analysis_source")
        with h5py.File(out / "c.h5") as f:
            force = {name: f[name][()] for name in ("t_s", "f_contact_n", "u95_n", "filters/taps_wfs")}
            attrs = {k: v for k, v in f.attrs.items() if k not in ("created", "campaign_analysis")}
            force["campaign_analysis"] = f.attrs["campaign_analysis"]
        rows = pq.read_table(next((out / "index").glob("**/*.parquet"))).to_pylist()
        return {
            "source": source,
            "json": doc,
            "report": (out / "report" / "report.html").read_text(encoding="utf-8"),
            "uff": (out / "f.uff").read_bytes(),
            "force": force,
            "attrs": attrs,
            "index": [{k: v for k, v in row.items() if k not in INDEX_TIMES} for row in rows],
        }

    stored = outputs("stored")
    assert fits == []  # nothing was fitted by any of the five commands
    refit = outputs("refit", "--reanalyse")
    assert len(fits) == 5 * 3  # every command fitted the three analysed runs
    assert stored.pop("source").startswith("as stored after each run")
    assert refit.pop("source") == "analysed again: asked (--reanalyse)"
    assert stored["force"].pop("campaign_analysis").startswith("as stored after each run")
    assert refit["force"].pop("campaign_analysis") == "analysed again: asked (--reanalyse)"
    assert stored["force"] and set(stored) == set(refit)
    for name in stored:
        assert_same(stored[name], refit[name], name)


def test_a_file_without_records_is_fitted_once_and_says_why(recorded, fits):
    with h5py.File(recorded, "r+") as f:  # as a file written before records were kept
        for run in f["runs"].values():
            run.pop("analysis", None)
    first = wfsbench("analyze", str(recorded))
    assert first.returncode == ExitCode.OK, first.stderr
    assert "== analysis analysed again: run smoke-s003-free_run has no stored analysis\n" in first.stdout
    assert len(fits) == 3
    second = wfsbench("analyze", str(recorded))  # the records the first stored
    assert "== analysis as stored after each run by wfs-bench " in second.stdout and len(fits) == 3
    said = [re.sub(r"; stored as results/\S+\)$", ")", line) for line in first.stdout.splitlines()]
    assert second.stdout.splitlines()[3:] == said[3:]  # after the metadata and the analysis's source


@pytest.mark.parametrize(
    ("garbage", "why"),
    [
        ("{not json", "not JSON"),
        ('{"format": 99}', "record format 99, this version reads 3 and 4"),
        ("[1, 2]", "not a JSON object"),
    ],
)
def test_a_record_that_cannot_be_read_is_fitted_again_naming_it(recorded, fits, garbage, why):
    with h5py.File(recorded, "r+") as f:
        del f[f"runs/{GRID_RUN}/analysis"]
        f[f"runs/{GRID_RUN}"].create_dataset("analysis", data=garbage, dtype=h5py.string_dtype())
    analysis = analyze_campaign(recorded)
    said = f"analysed again: the stored analysis of run {GRID_RUN} cannot be read: "
    assert analysis.source.startswith(said)
    assert why in analysis.source and len(fits) == 3


def test_a_record_with_a_wrong_member_is_refused_whole_naming_its_place(recorded):
    with open_campaign(recorded) as campaign:
        tree = json.loads(campaign.run(GRID_RUN).analysis_record)
    shaker = next(change for change in tree["changes"] if change[0] == "shaker")
    amplitude = shaker[2][0][1]["amplitudes"][0][1]
    amplitude["identification"]["best"] = 7  # no tyre model
    with pytest.raises(TypedFormatError, match=r"shaker\[0\]\.amplitudes\[0\]\.identification\.best: 7"):
        parse_record(json.dumps(tree))
    amplitude["identification"]["best"] = "two"
    with pytest.raises(TypedFormatError, match=r"identification\.best: 'two' is not a valid TyreModel"):
        parse_record(json.dumps(tree))
    del amplitude["valid_band_raw"]
    with pytest.raises(TypedFormatError, match=r"amplitudes\[0\]: not a ShakerAmplitudeResult"):
        parse_record(json.dumps(tree))


@dataclasses.dataclass(frozen=True)
class _Sample:
    ratio: float
    gain: complex
    model: TyreModel
    spectrum: np.ndarray
    by_key: dict[tuple[TyreModel, bool], float]
    noise: float | np.ndarray
    names: tuple[str, ...]
    band: tuple[float, float] | None = None


def test_the_codec_keeps_what_json_has_no_word_for():
    """Non-finite floats, complex numbers, enums, tuple keys, complex and boolean arrays."""
    sample = _Sample(
        ratio=float("nan"),
        gain=complex(1.5, -float("inf")),
        model=TyreModel.WHEEL_TREAD,
        spectrum=np.array([[1 + 2j, np.nan], [3, -np.inf]]),
        by_key={(TyreModel.WHEEL, True): 0.1 + 0.2},
        noise=np.array([True, False]),
        names=(),
    )
    text = json.dumps(to_json_tree(sample, _Sample), allow_nan=False)
    back = from_json_tree(json.loads(text), _Sample)
    assert_same(sample, back)
    either = float | np.ndarray
    assert from_json_tree(json.loads(json.dumps(to_json_tree(2.5, either))), either) == 2.5
    with pytest.raises(TypedFormatError, match=r"\.ratio: 'fast' is not a float"):
        from_json_tree({**json.loads(text), "ratio": "fast"}, _Sample)
    with pytest.raises(TypedFormatError, match=r"\.spectrum: not an array"):
        odd = {"dtype": "object", "shape": [1], "data": [1]}
        from_json_tree({**json.loads(text), "spectrum": odd}, _Sample)
    with pytest.raises(TypeError, match=r"does not know"):
        to_json_tree(object(), set[int])


def test_the_knowledge_of_every_kind_survives_the_record(recorded):
    """A knowledge as a reader rebuilds it from the records holds every run's analysis as made."""
    stored = analyze_campaign(recorded)
    assert isinstance(stored.knowledge, CampaignKnowledge)
    assert all(isinstance(run, RunAnalysis) for run in stored.runs)
    assert list(stored.knowledge.analysed_runs) == [run.run_id for run in stored.runs]
    assert stored.knowledge.shaker_free_run == []  # the raw records stay in the runs
