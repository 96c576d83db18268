"""The report's figures drawn by the post-run analysis and kept beside the runs (bench/app/kept_figures.py).

On the smoke campaign the simulated bench recorded (its post-run analysis ran as on a lab PC): the
file keeps the two shaker figures, h5dump reads them back, and ``report`` takes them without drawing,
byte for byte what ``--reanalyse`` draws. A kept figure that shows other values, is damaged, is laid
out otherwise, or is missing (a file written before figures were kept) is drawn again, and the
report is the same.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.app.analyze import analyze_campaign
from bench.app.kept_figures import PNG_SIGNATURE, DrawnFigures, FigureDrawer, shows_sha256
from bench.app.report import write_report
from bench.app.run_analysis import initial_knowledge, run_inputs
from bench.config import default_bench_config
from bench.models.benches import TyreModel
from bench.report import figures
from bench.report.figure_list import FigureKind, FigureSpec
from bench.store import CampaignWriter, StoreError, open_campaign
from bench.store import schema as s
from sequences.channels import Channel
from sequences.runs import RunKind
from tests.commands import wfsbench

H5DUMP = shutil.which("h5dump")
SHAKER_FIGURES = ("shaker_2p5bar", "shaker_compensated_2p5bar")


@pytest.fixture(scope="module")
def refit_pngs(smoke_campaign, tmp_path_factory) -> dict[str, bytes]:
    """The smoke campaign's figures as ``report --reanalyse`` draws them, by name."""
    written = write_report(smoke_campaign, tmp_path_factory.mktemp("refit"), reanalyse=True)
    assert set(written.drawn) == set(SHAKER_FIGURES)
    return {figure.name: figure.path.read_bytes() for figure in written.figures}


@pytest.fixture
def smoke_copy(smoke_campaign, tmp_path) -> Path:
    out = tmp_path / "smoke.h5"
    shutil.copyfile(smoke_campaign, out)
    return out


def _kept_datasets(path: Path) -> dict[str, str]:
    """figure name -> the dataset that keeps it."""
    found = {}
    with h5py.File(path, "r") as f:
        for run_id, run in f[s.RUNS].items():
            for name in run.get(s.FIGURES, {}):
                found[name] = f"/{s.RUNS}/{run_id}/{s.FIGURES}/{name}"
    return found


def _report_pngs(path: Path, out: Path) -> tuple[dict[str, bytes], tuple[str, ...]]:
    written = write_report(path, out)
    return {figure.name: figure.path.read_bytes() for figure in written.figures}, written.drawn


@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_the_report_takes_the_kept_figures_which_are_what_a_refit_draws(smoke_campaign, refit_pngs, tmp_path):
    kept = _kept_datasets(smoke_campaign)
    assert sorted(kept) == sorted(SHAKER_FIGURES)
    for name, dataset in kept.items():  # an independent reader gives the same PNG
        raw = tmp_path / f"{name}.bin"
        command = [H5DUMP, "-d", dataset, "-b", "LE", "-o", str(raw), str(smoke_campaign)]
        dump = subprocess.run(command, capture_output=True, text=True, timeout=60, check=False)
        assert dump.returncode == 0, dump.stdout + dump.stderr
        assert raw.read_bytes() == refit_pngs[name]
    pngs, drawn = _report_pngs(smoke_campaign, tmp_path / "report")
    assert drawn == ()
    assert pngs == refit_pngs


def test_the_report_command_says_how_many_figures_it_took_and_drew(smoke_campaign, tmp_path):
    run = wfsbench("report", str(smoke_campaign), "--out", str(tmp_path / "report"))
    assert run.returncode == 0, run.stderr
    assert "2 figures as the post-run analysis drew them, 0 drawn" in run.stdout.splitlines()
    again = wfsbench("report", "--reanalyse", str(smoke_campaign), "--out", str(tmp_path / "refit"))
    assert "0 figures as the post-run analysis drew them, 2 drawn" in again.stdout.splitlines()


def _restamp(figure: h5py.Dataset) -> None:
    figure.attrs[s.FIGURE_SHOWS] = "0" * 64


def _damage(figure: h5py.Dataset) -> None:
    figure[100:110] = 0


def _relayout(figure: h5py.Dataset) -> None:
    group, name = figure.parent, figure.name.rsplit("/", 1)[-1]
    del group[name]
    group.create_dataset(name, data=np.arange(5.0))


@pytest.mark.parametrize(
    "spoil",
    [_restamp, _damage, _relayout],
    ids=["shows other values", "damaged bytes", "not a PNG dataset"],
)
def test_a_kept_figure_that_cannot_be_taken_is_drawn_again(smoke_copy, refit_pngs, tmp_path, spoil):
    dataset = _kept_datasets(smoke_copy)["shaker_2p5bar"]
    with h5py.File(smoke_copy, "r+") as f:
        spoil(f[dataset])
    pngs, drawn = _report_pngs(smoke_copy, tmp_path / "report")
    assert drawn == ("shaker_2p5bar",)
    assert pngs == refit_pngs


def test_a_file_written_before_figures_were_kept_reports_alike(smoke_copy, refit_pngs, tmp_path):
    with h5py.File(smoke_copy, "r+") as f:
        for run in f[s.RUNS].values():
            if s.FIGURES in run:
                del run[s.FIGURES]
    pngs, drawn = _report_pngs(smoke_copy, tmp_path / "report")
    assert sorted(drawn) == sorted(SHAKER_FIGURES)
    assert pngs == refit_pngs


def test_the_drawer_draws_what_changed_once_and_counts_a_known_campaign_as_drawn(smoke_campaign, refit_pngs):
    analysis = analyze_campaign(smoke_campaign)
    with open_campaign(smoke_campaign) as campaign:
        grid = run_inputs(next(run for run in campaign.runs if run.kind == "dwell_grid"), campaign)
    drawer = FigureDrawer(initial_knowledge(default_bench_config()))
    drawn = drawer.after(grid, analysis.knowledge)
    assert {figure.name: figure.png for figure in drawn.kept} == refit_pngs and drawn.failed == ()
    assert drawer.after(grid, analysis.knowledge) == DrawnFigures()
    assert FigureDrawer(analysis.knowledge).after(grid, analysis.knowledge) == DrawnFigures()
    # a run analysed again, whose figures its campaign kept already: none drawn, none again after
    again = FigureDrawer(initial_knowledge(default_bench_config()))
    assert again.after(grid, analysis.knowledge, draw=False) == DrawnFigures()
    assert again.after(grid, analysis.knowledge) == DrawnFigures()


def test_a_figure_that_fails_to_draw_is_said_and_the_others_are_kept(smoke_campaign, refit_pngs, monkeypatch):
    analysis = analyze_campaign(smoke_campaign)
    with open_campaign(smoke_campaign) as campaign:
        grid = run_inputs(next(run for run in campaign.runs if run.kind == "dwell_grid"), campaign)
    drawing = figures.figure_png

    def failing(spec: FigureSpec) -> bytes:
        if spec.name == "shaker_2p5bar":
            raise RuntimeError("no canvas")
        return drawing(spec)

    monkeypatch.setattr(figures, "figure_png", failing)
    drawer = FigureDrawer(initial_knowledge(default_bench_config()))
    drawn = drawer.after(grid, analysis.knowledge)
    assert [(f.name, f.png) for f in drawn.kept] == [
        ("shaker_compensated_2p5bar", refit_pngs["shaker_compensated_2p5bar"])
    ]
    assert drawn.failed == ("figure shaker_2p5bar not drawn: RuntimeError: no canvas",)
    assert drawer.after(grid, analysis.knowledge) == DrawnFigures()  # tried again once its values change


def _digest(*shows: object) -> str:
    return shows_sha256(FigureSpec("shaker_1bar", FigureKind.SHAKER, "", "", shows))


def test_what_a_figure_shows_is_digested_by_value_whatever_the_number_type():
    values = {"k_t": np.float64(2.5e5), "curve": np.linspace(0.0, 1.0, 5)}
    assert _digest(1, values) == _digest(np.float64(1.0), {"k_t": 250000.0, "curve": np.linspace(0, 1, 5)})
    assert _digest(1, values) != _digest(1, {**values, "k_t": 2.5e5 * (1 + 1e-15)})
    assert _digest(1, values) != _digest(1, {**values, "curve": np.linspace(0.0, 1.0, 5).astype(np.float32)})
    assert _digest((1, 2)) == _digest([1, 2]) != _digest((2, 1))
    # a record read back: every NaN numpy's own, enums as their values
    with np.errstate(invalid="ignore"):  # 0/0: a NaN with its sign bit set, as x86 makes it
        made_nan = np.array([0.0, 1.0]) / np.array([0.0, 1.0])
    assert _digest(made_nan) == _digest(np.array([np.nan, 1.0]))
    assert _digest(TyreModel.WHEEL_TREAD, RunKind.SWEEP) == _digest(2, "sweep")
    with pytest.raises(TypeError, match="object has no digest by value"):
        _digest(object())


def test_a_figure_is_kept_once_per_run(tmp_path):
    writer = CampaignWriter.create(
        tmp_path / "c.h5", software_version="0", config_toml="", sequence_toml="", sequence_name="s"
    )
    channels = [Channel("fz_wfs_n", "N")]
    run = writer.begin_run(
        "001", kind="free_run", step={}, conditions={}, channels=channels, sample_rate_hz=1e3
    )
    run.finish("complete")
    run.write_figure("hammer", PNG_SIGNATURE, "0" * 64)
    with pytest.raises(StoreError, match="exists already: a figure is kept once"):
        run.write_figure("hammer", PNG_SIGNATURE, "1" * 64)
    writer.close()
    with open_campaign(tmp_path / "c.h5") as campaign:
        (kept,) = campaign.runs[0].figures().values()
    assert kept.png == PNG_SIGNATURE and kept.shows_sha256 == "0" * 64
