"""``wfsbench compensate``: a road drive on the simulated quarter car compensated with what a
simulated campaign (the paper's tyre at 2.5 bar on the shaker at 1 / 2 / 5 mm, the car's corner on
the four-post bench) identified; the goals of docs/compensate.md, the refusals, the filter export."""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

import bench.app.compensate as compensate_module
from bench.analysis.measurement_compensation import CompensationStream, design_filters
from bench.analysis.records import WHEEL_CHANNELS
from bench.analysis.shaker_models import LINEAR
from bench.app.analyze import analyze_campaign
from bench.app.compensate import (
    CompensationRefusedError,
    _tyre_alternatives,
    compensation_basis,
    prepare_compensation,
)
from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.models.benches import TyreModel
from bench.models.road import road_drive
from bench.models.setup import BenchSetup
from bench.simulated_campaign import (
    FREE_RUN_GRID_HZ,
    simulate_dwells,
)
from bench.simulated_road import BENCH_CHAIN, simulate_road, validate_on_road
from bench.store.measurement import (
    Measurement,
    MeasurementError,
    MissingChannelError,
    NotOnTheTyreError,
    read_measurement,
)
from tests.campaign_files import StoredRun, paper_corner_runs, write_analysed_campaign, write_campaign
from tests.documented import assert_documented
from tests.made_once import made_once

CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)


@pytest.fixture(scope="module")
def campaign(shared_folder) -> Path:
    """The paper's procedure at one pressure, written as a campaign file with its analysis stored
    (once per test run): the shaker's free run, the 2.5 bar grids at 1 / 2 / 5 mm, the post's free
    run and the four-post sweep of the car's corner."""
    return made_once(
        shared_folder, "corner-2.5-bar.h5", lambda path: write_analysed_campaign(path, paper_corner_runs(CAR))
    )


@pytest.fixture(scope="module")
def analysis(campaign):
    return analyze_campaign(campaign)


@pytest.fixture(scope="module")
def road(tmp_path_factory) -> tuple[Path, np.ndarray, np.ndarray]:
    """A class C road at 60 km/h, 20 s at 1 kHz, as a CSV measurement (``t_s``, ``fz_wfs_n``,
    ``a_hub_m_s2``), with its channels and true contact force."""
    record = simulate_road(
        CAR, road_drive("C", speed_km_h=60, duration_s=20, sample_rate_hz=1000, seed=5), seed=7
    )
    ch = record.channels
    path = tmp_path_factory.mktemp("road") / "road.csv"
    t = np.arange(ch["fz_wfs_n"].size) / record.sample_rate_hz
    columns = np.column_stack([t, ch["fz_wfs_n"], ch["a_hub_m_s2"]])
    np.savetxt(path, columns, delimiter=",", header="t_s,fz_wfs_n,a_hub_m_s2", comments="", fmt="%.17g")
    return path, columns, ch["f_contact_n"]


@pytest.mark.parametrize(("road_class", "speed_km_h"), [("C", 60.0), ("B", 100.0)])
def test_the_model_compensated_force_follows_the_true_force_within_its_band(analysis, road_class, speed_km_h):
    drive = road_drive(road_class, speed_km_h=speed_km_h, duration_s=20, sample_rate_hz=1000, seed=5)
    result = validate_on_road(analysis, CAR, drive, pressure_bar=2.5, seed=7)
    # the goal: the true force inside the 95 % band in at least 90 % of the samples, within the
    # valid band (both forces limited to it: outside it the compensation claims nothing)
    assert result.coverage_valid_band >= 0.90
    # far below the raw and the hub-acceleration compensated errors in 0-30 Hz and in every octave
    assert result.model_compensated.rms_n < 0.05 * result.hub_compensated.rms_n < 0.05 * result.raw.rms_n
    for model, raw in zip(result.model_compensated.octave_rms_n, result.raw.octave_rms_n, strict=True):
        assert model < raw
    # and small against the force itself: within 0.5 % of its rms (measured 0.1 %)
    assert result.model_compensated.rms_n < 0.005 * result.truth_rms_n
    assert result.valid_band_hz[1] == pytest.approx(
        analysis.knowledge.four_post.valid_band_model_compensated.upper_hz
    )


#: The campaign's car with the same tyre, linear: no stiffness rise, no friction.
LINEAR_CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD, nonlinear=False)


@pytest.mark.parametrize(
    ("road_class", "speed_km_h", "held_without_it"), [("C", 60.0, False), ("B", 100.0, True)]
)
def test_a_road_tyre_without_the_benchs_rate_and_amplitude_dependence_lies_in_the_band(
    analysis, road_class, speed_km_h, held_without_it, monkeypatch
):
    """The campaign's tyre rises 3 % per decade in stiffness and has friction; the road's is linear.
    The band's model-form part holds the other amplitudes and the chosen model fitted without
    rubber terms, so the true force lies inside it in at least 90 % of the samples within the valid
    band; without that alternative the class C road at 60 km/h falls short (printed with ``-s``)."""
    drive = road_drive(road_class, speed_km_h=speed_km_h, duration_s=20, sample_rate_hz=1000, seed=5)
    record = simulate_road(LINEAR_CAR, drive, seed=7)
    measurement = Measurement("road", record.sample_rate_hz, record.channels, chain=BENCH_CHAIN)
    alternatives = compensation_basis(analysis, measurement, 2.5)[0].alternatives
    assert [a.linear_fit for a in alternatives] == [False, False, True]
    assert alternatives[-1].rubber == LINEAR
    assert f"{alternatives[-1].label.removesuffix(' fitted without rubber terms')} (Model" in (
        compensation_basis(analysis, measurement, 2.5)[0].label
    )
    result = validate_on_road(analysis, LINEAR_CAR, drive, pressure_bar=2.5, seed=7)
    assert result.coverage_valid_band >= 0.90

    def without_the_linear_fit(amplitudes, chosen_m):
        return tuple(a for a in _tyre_alternatives(amplitudes, chosen_m) if not a.linear_fit)

    monkeypatch.setattr(compensate_module, "_tyre_alternatives", without_the_linear_fit)
    without = validate_on_road(analysis, LINEAR_CAR, drive, pressure_bar=2.5, seed=7)
    inside, inside_without = result.coverage_valid_band, without.coverage_valid_band
    print(f"\n  inside the band: {inside:.1%}, without the linear fit {inside_without:.1%}")
    assert (without.coverage_valid_band >= 0.90) == held_without_it


def test_the_stream_in_blocks_is_the_whole_records_filter(analysis, road):
    _, columns, _ = road
    m = Measurement("road", 1000.0, {"fz_wfs_n": columns[:, 1], "a_hub_m_s2": columns[:, 2]})
    compensation = prepare_compensation(analysis, m, 2.5)
    a_hub = columns[:, 2] - compensation.accelerometer_offset_m_s2
    whole = compensation.filters.compensator.apply(columns[:, 1], a_hub)
    # a small FFT makes many blocks: each joins its neighbours without a seam
    blocks = list(CompensationStream(compensation.filters, fft_size=1024).blocks(columns[:, 1], a_hub))
    assert len(blocks) > 20
    force = np.concatenate([b.force_n for b in blocks])
    assert np.array_equal(np.isnan(force), np.isnan(whole))
    assert np.nanmax(np.abs(force - whole)) < 1e-9 * np.nanmax(np.abs(whole))


def _order(x: float) -> str:
    """``x`` to one significant digit, as a document writes it: 3e-5, not 3e-05."""
    return f"{x:.0e}".replace("e-0", "e-").replace("e+00", "")


def test_the_linearised_band_is_the_spread_of_a_monte_carlo_over_the_parameters(analysis, road):
    """The parameters' part of the band: s^T C s against 40 seeded draws of the parameters, each
    with its own filters (the amplitude dependence and the noise left out)."""
    _, columns, _ = road
    m = Measurement("road", 1000.0, {"fz_wfs_n": columns[:, 1], "a_hub_m_s2": columns[:, 2]})
    basis = prepare_compensation(analysis, m, 2.5).filters.basis
    # how closely the fit determines k, m_T and d (relative half-widths of their 95 % intervals):
    # what docs/compensate.md quotes (seeded; printed with -s)
    half = [
        1.96 * np.sqrt(basis.covariance[j, j]) / abs(basis.value(name))
        for j, name in enumerate(basis.parameters)
        if name in ("stiffness_n_per_m", "tread_mass_kg", "damping_ns_per_m")
    ]
    assert len(half) == 3
    text = f"the fit determines k, m_T and d to {_order(min(half))}-{_order(max(half))}"
    print(f"\n  {text}")
    assert_documented("docs/compensate.md", text)
    basis = replace(basis, alternatives=(), noise_wfs_n=0.0, noise_accel_m_s2=0.0)
    filters = design_filters(basis, 1000.0)
    f_wfs, a_hub = columns[:, 1], columns[:, 2] - columns[:, 2].mean()
    linear_u95 = np.concatenate([b.u95_n for b in CompensationStream(filters).blocks(f_wfs, a_hub)])
    rng = np.random.default_rng(3)
    draws = rng.multivariate_normal([basis.value(n) for n in basis.parameters], basis.covariance, size=40)
    forces = []
    for draw in draws:
        drawn = replace(basis, parameters=(), covariance=np.zeros((0, 0)))
        for name, value in zip(basis.parameters, draw, strict=True):
            tyre, rubber, sensor = drawn.with_parameter(name, value)
            drawn = replace(drawn, tyre=tyre, rubber=rubber, sensor=sensor)
        comp = design_filters(drawn, 1000.0)
        forces.append(comp.compensator.apply(f_wfs, a_hub))
    ok = np.isfinite(linear_u95)
    spread = np.std(np.array(forces)[:, ok], axis=0, ddof=1)
    # the standard deviation of 40 draws scatters by 1/sqrt(2 x 39) = 11 % about the truth
    ratio = np.median(1.96 * spread / linear_u95[ok])
    assert 0.8 < ratio < 1.2


def test_the_command_writes_the_force_and_the_exported_filters_reproduce_it(
    campaign, analysis, road, tmp_path, capsys
):
    path, columns, truth = road
    out, exported, table = tmp_path / "out.h5", tmp_path / "filters.json", tmp_path / "filters.csv"
    # the road was read by the bench's own sensors: its accelerometer is the campaign's
    args = ["compensate", str(campaign), str(path), "--pressure", "2.5", "--hub-lag-ms", "campaign"]
    args += ["--out", str(out)]
    assert main([*args, "--filters", str(exported)]) == ExitCode.OK
    said = capsys.readouterr().out
    assert main(args) == ExitCode.INVALID  # the output is never replaced
    with h5py.File(out, "r") as f:
        force, u95, t = f["f_contact_n"][()], f["u95_n"][()], f["t_s"][()]
        assert f.attrs["schema"] == "wfs-bench compensated force"
        assert f["f_contact_n"].attrs["unit"] == "N"
        valid_band = tuple(f.attrs["valid_band_hz"])
    assert f"valid band {valid_band[0]:.4g}-{valid_band[1]:.4g} Hz" in said  # four digits, as everywhere
    assert not re.search(r"valid band \d+\.\d{5,}", said)
    assert np.array_equal(t, columns[:, 0])
    doc = json.loads(exported.read_text())
    h_f, h_a, latency = np.array(doc["taps_wfs"]), np.array(doc["taps_accel"]), doc["latency_samples"]
    assert doc["latency_ms"] == pytest.approx(1e3 * latency / doc["sample_rate_hz"])
    assert tuple(doc["valid_band_hz"]) == valid_band
    # the rule the export states, applied by plain convolution
    stream = np.convolve(columns[:, 1], h_f) + np.convolve(
        columns[:, 2] - doc["accelerometer_offset_m_s2"], h_a
    )
    aligned = stream[latency : latency + columns.shape[0]]
    ok = np.isfinite(force)
    assert ok.sum() == columns.shape[0] - (h_f.size - 1)
    # the output is stored as float32: equal to its rounding (6e-8 relative)
    assert np.abs(force[ok] - aligned[ok]).max() <= 1e-6 * np.abs(aligned[ok]).max()
    assert np.mean(np.abs(force[ok] - truth[ok]) <= u95[ok]) > 0.5  # unfiltered; the goal is in-band
    # the CSV export holds the same taps and description
    from bench.report.filters import write_filters

    measurement = replace(read_measurement(path, mapping=None), chain=BENCH_CHAIN)
    compensation = prepare_compensation(analysis, measurement, 2.5)
    write_filters(table, compensation.filters, compensation.accelerometer_offset_m_s2)
    with table.open() as f:
        lines = f.read().splitlines()
    described = dict(line[2:].split(": ", 1) for line in lines if line.startswith("# "))
    assert int(described["latency_samples"]) == latency and described["rule"] == doc["rule"]
    rows = list(csv.reader(line for line in lines if not line.startswith("#")))
    assert rows[0] == ["k", "taps_wfs", "taps_accel"] and rows[1] == ["sample", "N/N", "N/(m/s^2)"]
    assert np.array_equal(
        np.array([[float(r[1]), float(r[2])] for r in rows[2:]]), np.column_stack([h_f, h_a])
    )


def test_an_mdf4_measurement_reads_as_its_csv(road, tmp_path):
    from asammdf import MDF, Signal

    path, columns, _ = road
    mdf = MDF(version="4.10")
    t = columns[:, 0]
    mdf.append(
        [
            Signal(columns[:, 1] / 1e3, t, name="Fz_FL", unit="kN"),
            Signal(columns[:, 2] / 9.80665, t, name="a_FL", unit="g"),
        ]
    )
    mdf.save(tmp_path / "road.mf4", overwrite=True)
    mapping = tmp_path / "map.toml"
    mapping.write_text('[channels]\nfz_wfs_n = { column = "Fz_FL" }\na_hub_m_s2 = { column = "a_FL" }\n')
    from bench.store.csv_mapping import load_channel_mapping

    from_mdf = read_measurement(tmp_path / "road.mf4", mapping=load_channel_mapping(mapping))
    from_csv = read_measurement(path)
    assert from_mdf.sample_rate_hz == pytest.approx(from_csv.sample_rate_hz, rel=1e-9)
    for name in ("fz_wfs_n", "a_hub_m_s2"):
        assert np.allclose(from_mdf.channels[name], from_csv.channels[name], rtol=1e-12, atol=1e-9)
    with pytest.raises(
        MissingChannelError, match=r"no channel 'fz_wfs_n' for fz_wfs_n \(the file has Fz_FL, a_FL"
    ):
        read_measurement(tmp_path / "road.mf4")
    # a gap marked NaN is refused, named
    gap = columns[:, 1].copy()
    gap[1234] = np.nan
    mdf = MDF(version="4.10")
    mdf.append(
        [Signal(gap, t, name="fz_wfs_n", unit="N"), Signal(columns[:, 2], t, name="a_hub_m_s2", unit="m/s^2")]
    )
    mdf.save(tmp_path / "gap.mf4", overwrite=True)
    with pytest.raises(
        MeasurementError,
        match=r"fz_wfs_n has 1 samples that are not finite numbers, the first at sample 1234",
    ):
        read_measurement(tmp_path / "gap.mf4")


def test_a_measurement_the_campaign_does_not_cover_is_refused_naming_what_is_missing(
    analysis, road, tmp_path
):
    _, columns, _ = road
    channels = {"fz_wfs_n": columns[:, 1], "a_hub_m_s2": columns[:, 2]}
    at = {rate: Measurement("m.csv", rate, channels) for rate in (200.0, 1000.0, 20000.0)}
    with pytest.raises(
        CompensationRefusedError,
        match=r"tyre pressure 3\.5 bar: the campaign identified the tyre at 2\.5 bar only",
    ):
        prepare_compensation(analysis, at[1000.0], 3.5)
    with pytest.raises(CompensationRefusedError, match=r"tyre pressure is not known \(give --pressure BAR\)"):
        prepare_compensation(analysis, at[1000.0], None)
    with pytest.raises(
        CompensationRefusedError,
        match=r"sample rate 200 Hz cannot carry the compensation's band of 80\.5 Hz:"
        r" the filters need a rate above 241\.5 Hz",
    ):
        prepare_compensation(analysis, at[200.0], 2.5)
    with pytest.raises(
        CompensationRefusedError,
        match=r"sample rate 20000 Hz would need 3200 taps .* resample the measurement to at most 12800 Hz",
    ):
        prepare_compensation(analysis, at[20000.0], 2.5)
    # a CSV without the hub acceleration's column
    lacking = tmp_path / "no_hub.csv"
    np.savetxt(lacking, columns[:, :2], delimiter=",", header="t_s,fz_wfs_n", comments="")
    with pytest.raises(
        MissingChannelError,
        match=r"no_hub.csv: line 1, column 'a_hub_m_s2': missing: the compensation needs a_hub_m_s2"
        r" \(the header has: t_s, fz_wfs_n\)",
    ):
        read_measurement(lacking)


def test_the_command_refuses_with_exit_4_and_names_what_is_missing(campaign, tmp_path, capsys):
    out = tmp_path / "out.h5"
    # a run of the campaign file without the channels: the shaker's free run
    code = main(["compensate", str(campaign), str(campaign), "--run", "free", "--out", str(out)])
    assert code == ExitCode.REFUSED
    assert "run free: no fz_wfs_n, a_hub_m_s2 channel (it has z_base_m, f_plate_n)" in capsys.readouterr().err
    assert not out.exists()


def test_the_command_loads_no_device_client_simulator_engine_or_plotting(campaign, road, tmp_path):
    """``compensate`` is an offline command: in a fresh interpreter it loads none of
    tests/test_cli_imports.py's heavy modules."""
    from tests.test_cli_imports import run_offline

    path, _, _ = road
    code, loaded = run_offline(
        tmp_path, "compensate", str(campaign), str(path), "--pressure", "2.5", "--out", str(tmp_path / "o.h5")
    )
    assert (code, loaded) == (ExitCode.OK, [])


def test_a_run_recorded_without_the_wheel_is_refused_even_with_every_channel(tmp_path, capsys):
    """A free run (the wheel removed) records WFS Fz and the hub acceleration too, but no tyre's
    contact force: refused (exit 4) whatever pressure is given, not compensated into noise."""
    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ[:3], 2e-3, seed=4)
    runs = [StoredRun("bare", "free_run", tuple(free), {"wheel_fitted": False}, channels=WHEEL_CHANNELS)]
    path = write_campaign(tmp_path / "bare.h5", runs)
    with pytest.raises(NotOnTheTyreError, match=r"run bare \(free_run\) was recorded without the wheel"):
        read_measurement(path, run_id="bare")
    out = tmp_path / "out.h5"
    args = ["compensate", str(path), str(path), "--run", "bare", "--pressure", "2.5", "--out", str(out)]
    assert main(args) == ExitCode.REFUSED
    assert "without the wheel on the bench" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ("time,fz,acc\n0,1,2\n0.001,1,2\n", "'t_s'"),  # its own column names
        ("t_s;fz_wfs_n;a_hub_m_s2\n0;1;2\n", ""),  # another separator
    ],
    ids=["other column names", "semicolons"],
)
def test_a_csv_read_without_a_mapping_says_what_it_must_hold_and_names_the_mapping(tmp_path, text, said):
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(MeasurementError) as refused:
        read_measurement(path)
    assert "read without --mapping" in str(refused.value) and "docs/import.md" in str(refused.value)
    assert said in str(refused.value)


@pytest.mark.parametrize("pressure", ["nan", "inf", "-1", "0"])
def test_a_pressure_that_is_no_number_of_bar_is_refused_before_anything_is_read(tmp_path, capsys, pressure):
    out = tmp_path / "out.h5"
    args = ["compensate", str(tmp_path / "c.h5"), str(tmp_path / "m.csv"), f"--pressure={pressure}"]
    with pytest.raises(SystemExit) as refused:  # the command line's own refusal
        main([*args, "--out", str(out)])
    assert refused.value.code == ExitCode.INVALID
    assert "a tyre pressure must be a positive number of bar" in capsys.readouterr().err
    assert not out.exists()


def test_a_part_cut_from_a_longer_record_keeps_its_time(campaign, road, tmp_path, capsys):
    """The second half of the road, cut at a gap as the refusal of a gap advises: the output's time
    continues the record's (its CSV time column), not 0 again."""
    _, columns, _ = road
    half = columns[columns.shape[0] // 2 :]
    part, out = tmp_path / "part.csv", tmp_path / "part.h5"
    np.savetxt(part, half, delimiter=",", header="t_s,fz_wfs_n,a_hub_m_s2", comments="", fmt="%.17g")
    code = main(["compensate", str(campaign), str(part), "--pressure", "2.5", "--out", str(out)])
    assert code == ExitCode.OK
    with h5py.File(out, "r") as f:
        t = f["t_s"][()]
    assert t[0] == pytest.approx(10.0) and np.allclose(t, half[:, 0], rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "case",
    [
        ("1e300", "", "line 9, column 'fz_wfs_n': '1e300' is 1e+300 in SI units"),
        ("1e39", "", "line 9, column 'fz_wfs_n': '1e39' is 1e+39 in SI units"),  # float32: inf
        ("2000", "scale = 1e300", "line 2, column 'fz_wfs_n': '2000' is 2e+303 in SI units"),
    ],
    ids=["1e300 N", "1e39 N", "scale 1e300"],
)
def test_a_value_no_sensor_reads_is_refused_naming_its_line(campaign, tmp_path, capsys, case):
    """A damaged cell or a scale off by orders of magnitude: refused (exit 3) naming the line and
    the column, and no output; it was compensated into 81 % non-finite values before."""
    cell, mapping, said = case
    path, out = tmp_path / "m.csv", tmp_path / "out.h5"
    rows = [f"{i / 1000:.3f},{2000 + i},0.5" for i in range(2000)]
    rows[7] = f"0.007,{cell},0.5"
    path.write_text("t_s,fz_wfs_n,a_hub_m_s2\n" + "\n".join(rows) + "\n")
    args = ["compensate", str(campaign), str(path), "--pressure", "2.5", "--out", str(out)]
    if mapping:
        table = tmp_path / "mapping.toml"
        table.write_text(
            '[time]\ncolumn = "t_s"\nunit = "s"\n[channels]\n'
            f'fz_wfs_n = {{ column = "fz_wfs_n", unit = "N", {mapping} }}\n'
            'a_hub_m_s2 = { column = "a_hub_m_s2", unit = "m/s^2" }\n'
        )
        args += ["--mapping", str(table)]
    assert main(args) == ExitCode.INVALID
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}: {said}"), err
    assert "beyond +/-1e+15, no measured value (a damaged cell, or a wrong unit or scale" in err
    assert not out.exists()


@pytest.mark.parametrize("where", ["missing folder", "existing file"])
def test_a_filters_file_that_cannot_be_written_stops_everything_before_it_starts(
    campaign, road, tmp_path, capsys, where
):
    """``--filters`` into a folder that does not exist, or onto a file: refused (exit 3) before
    anything is computed, the output not written and the file there left as it was."""
    path, _, _ = road
    out = tmp_path / "out.h5"
    filters = tmp_path / "nowhere" / "filters.json"
    if where == "existing file":
        filters = tmp_path / "filters.json"
        filters.write_text("the lab's own\n")
    args = ["compensate", str(campaign), str(path), "--pressure", "2.5", "--out", str(out)]
    assert main([*args, "--filters", str(filters)]) == ExitCode.INVALID
    err = capsys.readouterr().err
    why = {
        "missing folder": f"no folder {tmp_path / 'nowhere'}",
        "existing file": "exists; it is never replaced (choose another name)",
    }[where]
    assert err == f"error: --filters {filters}: {why}\n"
    assert not out.exists()
    assert where == "missing folder" or filters.read_text() == "the lab's own\n"


def test_a_temporary_a_killed_process_left_is_removed_by_the_next_output(campaign, road, tmp_path, capsys):
    """A compensation killed while writing leaves its hidden temporary; the next command writing into
    the folder removes it, and leaves one of a process still running alone."""
    gone = subprocess.Popen(["true"])
    gone.wait()
    left = tmp_path / f".old.h5.{gone.pid}.partial"
    running = tmp_path / f".other.h5.{os.getppid()}.partial"
    left.write_bytes(b"half an HDF5 file")
    running.write_bytes(b"being written")
    path, _, _ = road
    out = tmp_path / "out.h5"
    code = main(["compensate", str(campaign), str(path), "--pressure", "2.5", "--out", str(out)])
    assert code == ExitCode.OK
    assert sorted(p.name for p in tmp_path.iterdir()) == [running.name, "out.h5"]


def test_a_run_exported_as_csv_compensates_without_a_mapping_as_the_run_itself(campaign, tmp_path, capsys):
    """``wfsbench export --format csv`` of the four-post sweep (a ``time_s`` column and a units
    row): read without a mapping, with the campaign's hub lag stated, it gives the force its run
    gives read from the campaign file, sample for sample."""
    folder, from_csv, from_run = tmp_path / "csv", tmp_path / "csv.h5", tmp_path / "run.h5"
    assert main(["export", str(campaign), "--format", "csv", "--run", "sweep", "--out", str(folder)]) == 0
    exported = folder / "sweep.csv"
    header, units = exported.read_text().splitlines()[:2]
    assert (header, units) == ("time_s,z_base_m,f_plate_n,fz_wfs_n,a_hub_m_s2", "s,m,N,N,m/s^2")
    stated = ["--hub-lag-ms", "campaign", "--pressure", "2.5"]  # what the run's file records itself
    assert main(["compensate", str(campaign), str(exported), *stated, "--out", str(from_csv)]) == 0
    assert main(["compensate", str(campaign), str(campaign), "--run", "sweep", "--out", str(from_run)]) == 0
    capsys.readouterr()
    with h5py.File(from_csv, "r") as csv_out, h5py.File(from_run, "r") as run_out:
        for name in ("t_s", "f_contact_n", "u95_n"):
            a, b = csv_out[name][()], run_out[name][()]
            # the file's samples read in blocks, the run's whole: sums in another order, the same
            # float32 output to a few of its steps at the largest value
            ulps = 4 * np.spacing(np.nanmax(np.abs(b)).astype(b.dtype))
            assert np.array_equal(np.isnan(a), np.isnan(b)), name
            assert np.nanmax(np.abs(a - b)) <= ulps, name


def test_a_units_row_of_units_no_compensation_reads_is_still_a_units_row(tmp_path):
    """As a recorded run's export has it: the speed in rad/s and an auxiliary channel in V."""
    path = tmp_path / "m.csv"
    rows = "\n".join(f"{k / 1000},0,{100 + k},0.5,1.2" for k in range(5))
    path.write_text(f"time_s,speed_rad_s,fz_wfs_n,a_hub_m_s2,aux3\ns,rad/s,N,m/s^2,V\n{rows}\n")
    measurement = read_measurement(path)
    assert measurement.sample_rate_hz == pytest.approx(1000.0)
    assert np.array_equal(np.asarray(measurement.channels["fz_wfs_n"][:]), 100.0 + np.arange(5))
