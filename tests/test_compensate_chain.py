"""``wfsbench compensate`` on a measurement whose chain is not the bench's: a road read by another
car's hub accelerometer (another lag) and a noisier WFS, a logger with its own anti-alias
bandwidth, a tyre pressure between or near the identified ones; what is stated is used, what is
not is said (docs/compensate.md, *The measurement's chain*; docs/analysis.md, *The band's noise*)."""

from __future__ import annotations

import functools
import json
import re
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.analysis.measurement_noise import estimable, noise_band_hz, white_noise_rms
from bench.app.analyze import analyze_campaign
from bench.app.compensate import CompensationRefusedError, prepare_compensation
from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.models.benches import TyreModel
from bench.models.road import road_drive
from bench.models.setup import BenchSetup
from bench.simulated_road import other_sensors, simulate_road, validate_on_road
from bench.store.measurement import Measurement
from bench.store.measurement_chain import MeasurementChain, Stated
from tests.campaign_files import paper_corner_runs, write_analysed_campaign
from tests.made_once import made_once

#: A long test module: in the validation tier (README.md, *Set up and run the tests*).
pytestmark = pytest.mark.validation

CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)
ROAD = road_drive("C", speed_km_h=60, duration_s=20, sample_rate_hz=1000, seed=5)
#: The road's sensors: an accelerometer of twice the bench's lag, a WFS three times as noisy.
OTHER = other_sensors(seed=9)
OTHER_LAG_MS = 1e3 * OTHER.accelerometer_lag_s
DOC = Path(__file__).resolve().parents[1] / "docs" / "compensate.md"
#: A mapping of the road's CSV (its time, its channels) before its ``measurement`` table.
MAPPING = (
    '[time]\ncolumn = "t_s"\nunit = "s"\n[channels]\nfz_wfs_n = { column = "fz_wfs_n", unit = "N" }\n'
    'a_hub_m_s2 = { column = "a_hub_m_s2", unit = "m/s^2" }\n'
)


@pytest.fixture(scope="module")
def campaigns(shared_folder) -> dict[str, Path]:
    """The paper's corner at 2.5 bar (1 / 2 / 5 mm) and 1.5 bar (2 mm) with its four-post run, and
    the same without the four-post run (a shaker-only campaign), each with its analysis stored
    (once per test run)."""
    runs = functools.cache(lambda: paper_corner_runs(CAR, more_pressures_bar=(1.5,)))
    return {
        "full": made_once(
            shared_folder, "corner-2.5-1.5-bar.h5", lambda path: write_analysed_campaign(path, runs())
        ),
        "shaker": made_once(
            shared_folder, "corner-shaker.h5", lambda path: write_analysed_campaign(path, runs()[:-2])
        ),
    }


@pytest.fixture(scope="module")
def analysis(campaigns):
    return analyze_campaign(campaigns["full"])


@pytest.fixture(scope="module")
def road(tmp_path_factory) -> Path:
    """The class C road at 60 km/h read by :data:`OTHER`, as a CSV measurement."""
    record = simulate_road(CAR, ROAD, seed=9, sensors=OTHER)
    return _csv(tmp_path_factory.mktemp("road") / "road.csv", record.channels, record.sample_rate_hz)


def _csv(path: Path, channels: dict[str, np.ndarray], fs_hz: float, step: int = 1) -> Path:
    fz, a_hub = channels["fz_wfs_n"][::step], channels["a_hub_m_s2"][::step]
    columns = np.column_stack([np.arange(fz.size) * step / fs_hz, fz, a_hub])
    np.savetxt(path, columns, delimiter=",", header="t_s,fz_wfs_n,a_hub_m_s2", comments="", fmt="%.17g")
    return path


def _compensate(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["compensate", *args])
    said = capsys.readouterr()
    return code, said.out, said.err


def _measurement(road_csv: Path, chain: MeasurementChain | None = None) -> Measurement:
    from bench.store.measurement import read_measurement

    return replace(read_measurement(road_csv), chain=chain or MeasurementChain())


# -- (i) another accelerometer and another WFS noise ----------------------------------------------


def test_with_its_lag_stated_the_true_force_lies_in_the_band_of_a_road_read_by_other_sensors(analysis):
    """Stated, the road's own accelerometer lag is undone and its own noise (about 3 N, the bench's
    about 1 N) is estimated from the measurement: the true force lies inside the 95 % band in at
    least 90 % of the samples within the valid band (the campaign's lag and noise: 14 %)."""
    stated = MeasurementChain(hub_lag_ms=Stated(OTHER_LAG_MS, "the road's accelerometer"))
    result = validate_on_road(analysis, CAR, ROAD, pressure_bar=2.5, seed=9, sensors=OTHER, chain=stated)
    assert result.hub_lag_ms == pytest.approx(0.75, rel=1e-3)
    assert result.coverage_valid_band >= 0.90
    # the band's noise is the measurement's, not the campaign's 0.94 N
    assert result.noise_wfs_n > 2.5
    assert any(line.startswith("measured: Fz noise") for line in result.assumptions)
    # unstated, the lag is taken as 0 (said): the band does not hold the error of 0.75 ms
    unstated = validate_on_road(analysis, CAR, ROAD, pressure_bar=2.5, seed=9, sensors=OTHER)
    assert unstated.hub_lag_ms == 0.0 and unstated.coverage_valid_band < 0.5
    assert any(line.startswith("assumed: hub accelerometer lag 0 ms") for line in unstated.assumptions)


def test_a_lag_not_stated_is_taken_as_zero_and_the_command_says_so(campaigns, road, tmp_path, capsys):
    """The campaign's four-post lag belongs to the bench's accelerometer: a CSV that states none is
    compensated with 0, said in the text, the JSON and the output file, with the lag the campaign
    measured and how to state the measurement's."""
    out = tmp_path / "out.h5"
    code, text, _ = _compensate(
        capsys, str(campaigns["full"]), str(road), "--pressure", "2.5", "--out", str(out)
    )
    assert code == ExitCode.OK
    line = next(line for line in text.splitlines() if "hub accelerometer lag" in line)
    assert re.fullmatch(
        r"assumed: hub accelerometer lag 0 ms undone: the measurement states none, so an accelerometer"
        r" without lag \(the campaign's four-post run measured 0\.3\d+ ms of its own accelerometer, not"
        r" applied to another's\); state it with --hub-lag-ms MS, or --hub-lag-ms campaign .*",
        line,
    )
    for what in ("tyre pressure", "logger bandwidth", "Fz noise", "hub acceleration noise", "valid band"):
        assert any(
            what in line and line.split(":")[0] in ("stated", "assumed", "campaign", "measured")
            for line in text.splitlines()
        ), what
    with h5py.File(out, "r") as f:
        assert f.attrs["hub_lag_source"] == "assumed" and f.attrs["hub_lag_ms"] == 0.0
        assert f.attrs["accelerometer_delay_s"] == 0.0
        assert f.attrs["campaign_hub_lag_ms"] == pytest.approx(0.375, rel=0.05)
        assert line in f.attrs["assumptions"].splitlines()
        assert (
            f.attrs["noise_wfs_n"] == f.attrs["noise_wfs_measured_n"] > 2.5 > f.attrs["noise_wfs_campaign_n"]
        )
        assert np.isnan(f.attrs["bandwidth_hz"])


def test_a_stated_lag_is_used_and_reported_in_the_json(campaigns, road, tmp_path, capsys):
    out = tmp_path / "out.h5"
    args = [str(campaigns["full"]), str(road), "--pressure", "2.5", "--out", str(out)]
    code, text, _ = _compensate(capsys, *args, "--hub-lag-ms", f"{OTHER_LAG_MS:.6f}", "--json")
    assert code == ExitCode.OK
    doc = json.loads(text)
    assert (doc["schema"], doc["version"]) == ("wfs-bench-compensate", 1)
    lag = doc["assumptions"]["hub_lag"]
    assert lag["source"] == "stated" and lag["hub_lag_ms"] == pytest.approx(OTHER_LAG_MS, rel=1e-6)
    assert lag["text"].endswith("as --hub-lag-ms states")
    noise = doc["assumptions"]["noise_wfs"]
    assert noise["source"] == "measured" and noise["noise_wfs_n"] == noise["noise_wfs_measured_n"]
    assert noise["noise_band_hz"] == pytest.approx([120.75, 300.0])
    assert set(doc["assumptions"]) == {
        "tyre_pressure",
        "hub_lag",
        "bandwidth",
        "noise_wfs",
        "noise_accel",
        "valid_band",
    }
    assert (
        doc["out"] == str(out) and doc["valid_band_hz"] == doc["assumptions"]["valid_band"]["valid_band_hz"]
    )
    with h5py.File(out, "r") as f:
        assert f.attrs["accelerometer_delay_s"] == pytest.approx(OTHER_LAG_MS / 1e3, rel=1e-6)
        assert f.attrs["hub_lag_source"] == "stated"


def test_a_run_of_the_campaign_file_itself_takes_its_four_post_lag_and_says_why(campaigns, tmp_path, capsys):
    out = tmp_path / "out.h5"
    campaign = str(campaigns["full"])
    code, text, _ = _compensate(capsys, campaign, campaign, "--run", "sweep", "--out", str(out), "--json")
    assert code == ExitCode.OK
    lag = json.loads(text)["assumptions"]["hub_lag"]
    assert lag["source"] == "campaign" and lag["hub_lag_ms"] == lag["campaign_hub_lag_ms"] > 0.3
    assert "a run of the campaign file itself" in lag["text"]


def test_the_lag_can_be_stated_in_the_mapping_and_the_command_line_must_agree(
    campaigns, road, tmp_path, capsys
):
    mapping = tmp_path / "map.toml"
    mapping.write_text(f"{MAPPING}[measurement]\nhub_lag_ms = 0.75\nbandwidth_hz = 200\n")
    args = [str(campaigns["full"]), str(road), "--pressure", "2.5", "--mapping", str(mapping)]
    code, text, _ = _compensate(capsys, *args, "--out", str(tmp_path / "a.h5"), "--json")
    assert code == ExitCode.OK
    stated = json.loads(text)["assumptions"]
    assert stated["hub_lag"]["hub_lag_ms"] == 0.75 and "measurement.hub_lag_ms" in stated["hub_lag"]["text"]
    assert stated["bandwidth"] == {
        "source": "stated",
        "text": f"logger bandwidth 200 Hz ({mapping}: measurement.bandwidth_hz)",
        "bandwidth_hz": 200.0,
    }
    # the noise is estimated below the logger's bandwidth
    assert stated["noise_wfs"]["noise_band_hz"] == pytest.approx([120.75, 200.0])
    code, _, err = _compensate(capsys, *args, "--hub-lag-ms", "0.5", "--out", str(tmp_path / "b.h5"))
    assert code == ExitCode.INVALID
    assert (
        err == f"error: --hub-lag-ms 0.5 contradicts the 0.75 that {mapping}: measurement.hub_lag_ms states\n"
    )


# -- (ii) a tyre pressure between or near the identified ones -------------------------------------


@pytest.mark.parametrize("pressure_bar", [2.0, 2.44, 1.56])
def test_a_pressure_between_identified_ones_is_refused_never_rounded(analysis, road, pressure_bar):
    with pytest.raises(
        CompensationRefusedError,
        match=rf"tyre pressure {pressure_bar:g} bar: lies between the campaign's identifications at 1\.5 and"
        r" 2\.5 bar \(within 0\.05 bar, a gauge's resolution, of neither\); the stiffness between pressures"
        r" is not known well enough to interpolate",
    ):
        prepare_compensation(analysis, _measurement(road), pressure_bar)


@pytest.mark.parametrize(
    ("pressure_bar", "identified_bar"), [(2.45, 2.5), (2.55, 2.5), (1.55, 1.5), (2.5, 2.5)]
)
def test_a_pressure_within_a_gauges_resolution_of_an_identified_one_is_taken_as_it_and_said(
    analysis, road, pressure_bar, identified_bar
):
    compensation = prepare_compensation(analysis, _measurement(road), pressure_bar)
    assert compensation.filters.basis.label.startswith(f"tyre at {identified_bar:g} bar")
    said = next(a for a in compensation.assumptions if a.key == "tyre_pressure")
    assert said.values == {"tyre_pressure_bar": pressure_bar, "identified_pressure_bar": identified_bar}
    if pressure_bar == identified_bar:
        assert said.source == "stated"
        return
    assert said.source == "assumed"
    assert said.text.startswith(
        f"tyre pressure {pressure_bar:g} bar taken as the campaign's identification at"
        f" {identified_bar:g} bar: within 0.05 bar, a gauge's resolution"
    )


def test_the_output_file_records_the_measurements_pressure_and_the_one_identified(
    campaigns, road, tmp_path, capsys
):
    out = tmp_path / "out.h5"
    code, text, _ = _compensate(
        capsys, str(campaigns["full"]), str(road), "--pressure", "2.45", "--out", str(out)
    )
    assert code == ExitCode.OK
    assert "assumed: tyre pressure 2.45 bar taken as the campaign's identification at 2.5 bar" in text
    with h5py.File(out, "r") as f:
        assert (f.attrs["tyre_pressure_bar"], f.attrs["identified_pressure_bar"]) == (2.45, 2.5)
        assert f.attrs["tyre_pressure_source"] == "assumed"


# -- (iii) the logger's bandwidth ends the valid band ---------------------------------------------


def test_a_stated_bandwidth_ends_the_valid_band(analysis, road):
    chain = MeasurementChain(bandwidth_hz=Stated(20.0, "--bandwidth-hz"))
    compensation = prepare_compensation(analysis, _measurement(road, chain), 2.5)
    lo, hi = compensation.filters.basis.valid_band_hz
    assert hi <= 20.0 and lo == pytest.approx(0.61, abs=0.01)
    said = {a.key: a for a in compensation.assumptions}
    assert said["bandwidth"].source == "stated"
    assert "the valid band ends there, not at the campaign's 29.17 Hz" in said["bandwidth"].text
    assert said["valid_band"].values["verified_band_hz"][1] == pytest.approx(29.17, abs=0.01)
    # below the stop band of the filters the measurement shows no noise band: the campaign's is used
    assert said["noise_wfs"].source == "campaign" and "not estimated" in said["noise_wfs"].text


def test_a_shaker_only_campaign_says_its_band_is_the_shakers_and_a_slow_logger_ends_it(
    campaigns, tmp_path, capsys
):
    """A 500 Hz measurement whose logger passes 30 Hz, with a campaign of the shaker alone: the
    band it verified (0.5-70 Hz, hub clamped) is said to be the shaker's, and ends at 30 Hz."""
    record = simulate_road(CAR, ROAD, seed=9, sensors=OTHER)
    slow = _csv(tmp_path / "slow.csv", record.channels, record.sample_rate_hz, step=2)
    args = [str(campaigns["shaker"]), str(slow), "--pressure", "2.5"]
    code, text, _ = _compensate(capsys, *args, "--out", str(tmp_path / "a.h5"))
    assert code == ExitCode.OK
    assert re.search(
        r"campaign: valid band 0\.5-70 Hz: the shaker's compensated band \(hub clamped\) only: the campaign"
        r" has no four-post run, so the hub acceleration's path is not verified",
        text,
    )
    code, text, _ = _compensate(
        capsys, *args, "--bandwidth-hz", "30", "--out", str(tmp_path / "b.h5"), "--json"
    )
    assert code == ExitCode.OK
    doc = json.loads(text)
    assert doc["sample_rate_hz"] == 500.0 and doc["valid_band_hz"] == [0.5, 30.0]
    with h5py.File(tmp_path / "b.h5", "r") as f:
        assert f.attrs["valid_band_hz"][1] <= 30.0 and f.attrs["bandwidth_hz"] == 30.0


@pytest.mark.parametrize(
    "case",
    [
        (
            "--bandwidth-hz",
            "600",
            ExitCode.INVALID,
            "error: --bandwidth-hz 600 Hz: above half the measurement's"
            " sample rate (500 Hz): no logger passes that",
        ),
        (
            "--bandwidth-hz",
            "0.4",
            ExitCode.REFUSED,
            "refused: --bandwidth-hz 0.4 Hz: the logger's bandwidth ends"
            " at or below the valid band's start, 0.6104 Hz: nothing of the compensation would be valid",
        ),
        (
            "--hub-lag-ms",
            "45",
            ExitCode.REFUSED,
            "refused: hub accelerometer lag 45 ms (as --hub-lag-ms states):"
            " the filters' latency of 40 ms cannot undo that much",
        ),
    ],
    ids=["bandwidth above half the rate", "bandwidth below the band", "lag beyond the latency"],
)
def test_a_chain_the_measurement_or_the_filters_cannot_have_is_refused_naming_it(
    campaigns, road, tmp_path, capsys, case
):
    option, value, code, said = case
    out = tmp_path / "out.h5"
    args = [str(campaigns["full"]), str(road), "--pressure", "2.5", option, value, "--out", str(out)]
    assert _compensate(capsys, *args)[::2] == (code, said + "\n")
    assert not out.exists()


def test_the_campaigns_lag_stated_for_a_campaign_without_a_four_post_run_is_refused(
    campaigns, road, tmp_path, capsys
):
    args = [str(campaigns["shaker"]), str(road), "--pressure", "2.5", "--hub-lag-ms", "campaign"]
    code, _, err = _compensate(capsys, *args, "--out", str(tmp_path / "out.h5"))
    assert code == ExitCode.REFUSED
    assert "--hub-lag-ms states the campaign's accelerometer, but the campaign has no four-post run" in err


# -- garbage in the new options and keys ----------------------------------------------------------


@pytest.mark.parametrize(
    ("option", "value", "said"),
    [
        ("--hub-lag-ms", "nan", "a hub accelerometer lag is a number of ms, 0 or more, or 'campaign'"),
        ("--hub-lag-ms", "-0.2", "a hub accelerometer lag is a number of ms, 0 or more, or 'campaign'"),
        ("--hub-lag-ms", "inf", "a hub accelerometer lag is a number of ms, 0 or more, or 'campaign'"),
        ("--hub-lag-ms", "fast", "a hub accelerometer lag is a number of ms, 0 or more, or 'campaign'"),
        ("--bandwidth-hz", "nan", "a logger's bandwidth is a number of Hz above 0"),
        ("--bandwidth-hz", "-30", "a logger's bandwidth is a number of Hz above 0"),
        ("--bandwidth-hz", "0", "a logger's bandwidth is a number of Hz above 0"),
        ("--bandwidth-hz", "30Hz", "a logger's bandwidth is a number of Hz above 0"),
    ],
)
def test_an_option_that_is_no_lag_or_bandwidth_is_refused_before_anything_is_read(
    tmp_path, capsys, option, value, said
):
    out = tmp_path / "out.h5"
    with pytest.raises(SystemExit) as refused:
        main(
            [
                "compensate",
                str(tmp_path / "c.h5"),
                str(tmp_path / "m.csv"),
                f"{option}={value}",
                "--out",
                str(out),
            ]
        )
    assert refused.value.code == ExitCode.INVALID
    err = capsys.readouterr().err
    assert f"argument {option}: {said}" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "case",
    [
        ("hub_lag_ms = nan", "measurement.hub_lag_ms: a hub accelerometer lag is a number of ms, 0 or more"),
        ("hub_lag_ms = -1", "measurement.hub_lag_ms: a hub accelerometer lag is a number of ms, 0 or more"),
        (
            'hub_lag_ms = "0.4"',
            "measurement.hub_lag_ms: a hub accelerometer lag is a number of ms, 0 or more",
        ),
        ("hub_lag_ms = true", "measurement.hub_lag_ms: a hub accelerometer lag is a number of ms, 0 or more"),
        ("bandwidth_hz = nan", "measurement.bandwidth_hz: a logger's bandwidth is a number of Hz above 0"),
        ("bandwidth_hz = -5", "measurement.bandwidth_hz: a logger's bandwidth is a number of Hz above 0"),
        ('bandwidth_hz = "wide"', "measurement.bandwidth_hz: a logger's bandwidth is a number of Hz above 0"),
        ("lag_ms = 0.4", "measurement.lag_ms: unknown key (allowed: hub_lag_ms, bandwidth_hz)"),
    ],
)
def test_a_mapping_that_states_no_lag_or_bandwidth_is_refused_naming_its_key(
    campaigns, road, tmp_path, capsys, case
):
    line, said = case
    mapping = tmp_path / "map.toml"
    mapping.write_text(f"{MAPPING}[measurement]\n{line}\n")
    out = tmp_path / "out.h5"
    args = [
        str(campaigns["full"]),
        str(road),
        "--pressure",
        "2.5",
        "--mapping",
        str(mapping),
        "--out",
        str(out),
    ]
    code, _, err = _compensate(capsys, *args)
    assert code == ExitCode.INVALID
    assert err.startswith(f"error: {mapping}: {said}")
    assert not out.exists()


# -- the noise estimate ---------------------------------------------------------------------------


def test_the_noise_estimate_reads_white_noise_under_the_force_and_no_band_where_there_is_none():
    rng = np.random.default_rng(4)
    fs = 1000.0
    t = np.arange(20_000) / fs
    force = 800 * np.sin(2 * np.pi * 12 * t) + 3.0 * rng.standard_normal(t.size)
    band = noise_band_hz(80.5, fs)
    assert band == pytest.approx((120.75, 300.0)) and estimable(band)
    # 20 s of 4 Hz bins over 180 Hz: the estimate scatters by about 0.4 %
    assert white_noise_rms(force, fs, band) == pytest.approx(3.0, rel=0.03)
    assert not estimable(noise_band_hz(80.5, 500.0, bandwidth_hz=30.0))  # a 30 Hz logger at 500 Hz
    assert not estimable(noise_band_hz(80.5, 300.0))  # 0.3 of the rate is below the stop band


# -- the output's layout as documented ------------------------------------------------------------


def test_every_root_attribute_of_the_output_is_documented_and_every_documented_one_written(
    campaigns, road, tmp_path, capsys
):
    out = tmp_path / "out.h5"
    assert (
        _compensate(capsys, str(campaigns["full"]), str(road), "--pressure", "2.5", "--out", str(out))[0] == 0
    )
    section = DOC.read_text().split("## The output (HDF5)", 1)[1].split("\n## ", 1)[0]
    documented = {
        name
        for cell in re.findall(r"^\| (`/@[^|]+`) \|", section, re.M)
        for name in re.findall(r"/@(\w+)", cell)
    }
    with h5py.File(out, "r") as f:
        written = set(f.attrs)
    # written only when the identification used is flagged (this campaign's is not)
    assert written == documented - {"identification_source"}


def test_an_identification_the_analysis_flagged_is_said_with_the_band(analysis):
    """The band's parameter part holds the fit's noise alone: a fit flagged as missing its data
    (a model that leaves something out) is said among the assumptions, with the flag's words."""
    from bench.app.compensate import _flagged_identification

    shaker = analysis.knowledge.shaker[2.5]
    chosen = next(iter(shaker.amplitudes.values()))
    assert _flagged_identification(chosen, 2.5) == ()  # the campaign's fits are not flagged
    finding = "Model 2 misses the data outside its noise (reduced chi^2 1.8; ...)"
    flagged = replace(chosen, identification=replace(chosen.identification, findings=(finding,)))
    (said,) = _flagged_identification(flagged, 2.5)
    assert (said.key, said.source) == ("identification", "campaign")
    assert said.line == (
        f"campaign: the tyre at 2.5 bar, {chosen.label} is flagged: {finding}; the band's part for its"
        " parameters holds their noise alone, not what the flag names"
    )
