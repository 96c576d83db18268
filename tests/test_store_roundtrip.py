"""Campaign store round trip: what the writer is given, the reader gives back, as analysis records."""

from __future__ import annotations

import math
from dataclasses import dataclass

import h5py
import numpy as np
import pytest

from bench.analysis.records import WHEEL_CHANNELS, fit_dwell_record
from bench.store import CampaignWriter, StoreError, open_campaign
from bench.store.schema import SCHEMA_NAME, SCHEMA_VERSION
from sequences.channels import Channel
from sequences.points import PointAttempt

FS_HZ = 1000.0
CHANNELS = (
    Channel("sample", "1", "acquisition sample index", "u4"),
    Channel("z_base_m", "m", "bench displacement (aux0)", "f4"),
    Channel("f_plate_n", "N", "plate force (aux1)", "f4"),
    Channel("fz_wfs_n", "N", "vertical WFS force", "f4"),
    Channel("a_hub_m_s2", "m/s^2", "hub acceleration (aux2)", "f4"),
    Channel("status", "1", "frame status bits", "u2"),
)
# dwells: (frequency Hz, amplitude mm); each 0.5 s taper, 2 s hold, 0.5 s taper
DWELLS = ((5.0, 2.0), (12.5, 2.0), (31.0, 1.0))
TAPER_S, HOLD_S = 0.5, 2.0


def _dwell_block(start: int, freq_hz: float, amplitude_mm: float) -> dict[str, np.ndarray]:
    n = round((2 * TAPER_S + HOLD_S) * FS_HZ)
    t = np.arange(n) / FS_HZ
    z = 1e-3 * amplitude_mm * np.sin(2 * np.pi * freq_hz * t)
    w = 2 * np.pi * freq_hz
    return {
        "sample": np.arange(start, start + n, dtype=np.uint32),
        "z_base_m": z,
        "f_plate_n": 3e5 * z,
        "fz_wfs_n": 2e5 * z,
        "a_hub_m_s2": -(w**2) * z,
        "status": np.zeros(n, dtype=np.uint16),
    }


def _write_grid(writer: CampaignWriter, run_id: str = "001-grid", *, block: int = 100):
    run = writer.begin_run(
        run_id,
        kind="dwell_grid",
        step={"type": "dwell_grid", "freqs_hz": [d[0] for d in DWELLS], "amplitudes_mm": [2.0, 1.0]},
        conditions={"tyre_pressure_bar": 2.4, "wheel_fitted": True},
        channels=CHANNELS,
        sample_rate_hz=FS_HZ,
    )
    written = []
    for index, (f, a) in enumerate(DWELLS):
        start = run.samples
        columns = _dwell_block(start, f, a)
        for i in range(0, len(columns["sample"]), block):
            run.append({k: v[i : i + block] for k, v in columns.items()})
        n_taper = round(TAPER_S * FS_HZ)
        row = PointAttempt(
            index=index,
            freq_hz=f,
            amplitude_mm=a,
            start_sample=start,
            hold_start_sample=start + n_taper,
            hold_end_sample=run.samples - n_taper,
            end_sample=run.samples,
            requested_amplitude_mm=a,
            commanded_amplitude_mm=a * 1.01,
            achieved_amplitude_mm=a * 0.99,
            note=f"dwell {index}",
            verdict="target",
            settle_s=0.25 + index,
            magnitude_uncertainty_pct=0.4,
            phase_uncertainty_deg=0.2,
            added_reason=f"steep {index}",
            amplitude_updates=index,
            held_amplitude_mm=a * 0.98,
            notched_by=f"limit {index}",
            notch_start_hz=f,
            notch_end_hz=f,
            notch_amplitude_mm=a * 0.5,
        )
        run.add_point(row)
        written.append((row, columns))
    return run, written


@pytest.fixture
def campaign(tmp_path):
    path = tmp_path / "campaign.h5"
    writer = CampaignWriter.create(
        path,
        software_version="0.1.0",
        config_toml='kind = "shaker"\n',
        sequence_toml='name = "smoke"\n',
        sequence_name="smoke.toml",
        config_name="simulated default",
    )
    return path, writer


def test_run_round_trip_gives_the_analysis_its_dwell_records(campaign):
    path, writer = campaign
    writer.add_event("prompt", "set the tyre pressure to 2.5 bar", answer_bar=2.4, target_bar=2.5)
    run, written = _write_grid(writer)
    run.add_event("interlock", "none", level=0)
    run.set_link_counters({"frames_ok": 9000, "frames_missing": 0, "gaps": 0})
    run.finish("complete", "")
    writer.close()

    with open_campaign(path) as campaign_file:
        assert (campaign_file.software_version, campaign_file.sequence_name) == ("0.1.0", "smoke.toml")
        assert campaign_file.config_toml == 'kind = "shaker"\n'
        assert campaign_file.events[0].fields == {"answer_bar": 2.4, "target_bar": 2.5}
        (view,) = campaign_file.runs
        assert (view.run_id, view.kind, view.status, view.reason) == (
            "001-grid",
            "dwell_grid",
            "complete",
            "",
        )
        assert view.conditions == {"tyre_pressure_bar": 2.4, "wheel_fitted": True}
        assert view.step["freqs_hz"] == [5.0, 12.5, 31.0]
        assert view.channel_specs == CHANNELS
        assert view.link_counters == {"frames_ok": 9000, "frames_missing": 0, "gaps": 0}
        assert [e.kind for e in view.events] == ["interlock"]
        assert view.events[0].sample == 9000
        assert [p for p in view.points] == [row for row, _ in written]
        assert view.completed_point_indices() == {0, 1, 2}
        assert view.channels["sample"].dtype == np.uint32
        np.testing.assert_array_equal(view.channels["sample"], np.arange(9000))

        records = view.dwell_records()
        assert len(records) == 3
        for record, (row, columns) in zip(records, written, strict=True):
            assert (record.freq_hz, record.amplitude_m) == (row.freq_hz, row.amplitude_mm * 1e-3)
            assert record.hold_s == (TAPER_S, TAPER_S + HOLD_S)
            for name in WHEEL_CHANNELS:  # float32 on disk: exact to float32 rounding
                np.testing.assert_array_equal(record.channels[name], columns[name].astype(np.float32))
            # the analysis fits the stored record: the sine's amplitude to float32 precision
            fit = fit_dwell_record(record, WHEEL_CHANNELS)
            assert fit.settled
            assert abs(fit.channels["z_base_m"].amplitude) == pytest.approx(row.amplitude_mm * 1e-3, rel=1e-5)
            assert fit.ratio("f_plate_n", "z_base_m")[0] == pytest.approx(3e5, rel=1e-5)


def test_results_are_nested_groups_read_back_as_written(campaign):
    path, writer = campaign
    run, _ = _write_grid(writer)
    run.finish("complete")

    @dataclass(frozen=True)
    class Interval:
        value: float
        low: float
        high: float

    result = {
        "m_comp_kg": 12.25,
        "parameters": {"k_n_m": Interval(3.9e5, 3.8e5, 4.0e5), "model": "model 2", "converged": True},
        "freqs_hz": np.linspace(0.5, 70, 22),
        "frf": np.exp(1j * np.linspace(0, 3, 22)),
        "valid_band_hz": None,
        "notes": ["settled", "one repeat"],
    }
    run.write_results("identification", result)
    with pytest.raises(StoreError, match="never overwritten"):
        run.write_results("identification", result)
    writer.close()

    with open_campaign(path) as f:
        view = f.runs[0]
        assert view.result_names == ("identification",)
        back = view.results("identification")
    assert back["m_comp_kg"] == 12.25
    assert back["parameters"] == {
        "k_n_m": {"value": 3.9e5, "low": 3.8e5, "high": 4.0e5},
        "model": "model 2",
        "converged": True,
    }
    np.testing.assert_array_equal(back["freqs_hz"], result["freqs_hz"])
    np.testing.assert_array_equal(back["frf"], result["frf"])
    assert back["valid_band_hz"] is None
    assert back["notes"] == ["settled", "one repeat"]


def test_unfinished_run_reads_incomplete_and_continues_with_each_point_once(campaign):
    path, writer = campaign
    run = writer.begin_run(
        "001-grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
    )
    first = _dwell_block(0, *DWELLS[0])
    run.append(first)
    run.add_point(PointAttempt(0, 5.0, 2.0, 0, 500, 2500, 3000))
    run.append(_dwell_block(3000, *DWELLS[1]) | {})  # point 1 interrupted before it was marked done
    writer.close()  # the writer stops without finish()

    with open_campaign(path) as f:
        assert f.runs[0].status == "incomplete"
        assert f.runs[0].completed_point_indices() == {0}

    writer = CampaignWriter.open_append(path)
    with pytest.raises(StoreError, match="exists already"):
        writer.begin_run(
            "001-grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=1
        )
    run = writer.continue_run("001-grid")
    assert run.samples == 6000
    with pytest.raises(StoreError, match="point 0 is done already"):
        run.add_point(PointAttempt(0, 5.0, 2.0, 0, 500, 2500, 3000))
    run.append(_dwell_block(6000, *DWELLS[1]))
    run.add_point(PointAttempt(1, 12.5, 2.0, 6000, 6500, 8500, 9000, attempt=2))
    run.finish("complete")
    writer.close()

    with open_campaign(path) as f:
        view = f.runs[0]
        assert view.status == "complete"
        assert [p.index for p in view.points] == [0, 1]
        assert [e.kind for e in view.events] == ["resumed"]
        assert view.events[0].fields == {"samples": 6000}
        assert [r.freq_hz for r in view.dwell_records()] == [5.0, 12.5]


def test_a_run_that_ended_early_continues_and_keeps_how_it_had_ended(campaign):
    path, writer = campaign
    run = writer.begin_run(
        "001-grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
    )
    run.append(_dwell_block(0, *DWELLS[0]))
    run.add_point(PointAttempt(0, 5.0, 2.0, 0, 500, 2500, 3000))
    run.finish("aborted", "aborted by the operator")  # Ctrl-C: a tapered stop, the run marked
    writer.close()

    writer = CampaignWriter.open_append(path)
    run = writer.continue_run("001-grid")
    with open_campaign(path) as f:  # open again until it finishes
        assert (f.runs[0].status, f.runs[0].reason, f.runs[0].finished) == ("incomplete", "", "")
    run.append(_dwell_block(3000, *DWELLS[1]))
    run.add_point(PointAttempt(1, 12.5, 2.0, 3000, 3500, 5500, 6000))
    run.finish("complete")
    with pytest.raises(StoreError, match="is complete; only a run that did not complete can be resumed"):
        writer.continue_run("001-grid")
    writer.close()

    with open_campaign(path) as f:
        view = f.runs[0]
        assert view.status == "complete"
        assert [p.index for p in view.points] == [0, 1]
        (resumed,) = view.events
        assert resumed.text == (
            "writing resumed after sample 3000; the run had ended aborted: aborted by the operator"
        )
        assert resumed.fields == {
            "samples": 3000,
            "ended": "aborted",
            "ended_reason": "aborted by the operator",
        }


def test_a_new_run_resumes_an_incomplete_one_without_repeating_its_points(campaign):
    path, writer = campaign
    run = writer.begin_run(
        "001-grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
    )
    run.append(_dwell_block(0, *DWELLS[0]))
    run.add_point(PointAttempt(0, 5.0, 2.0, 0, 500, 2500, 3000))
    writer.close()

    writer = CampaignWriter.open_append(path)
    run = writer.begin_run(
        "002-grid",
        kind="dwell_grid",
        step={},
        conditions={},
        channels=CHANNELS,
        sample_rate_hz=FS_HZ,
        resumes="001-grid",
    )
    with pytest.raises(StoreError, match="point 0 is done already"):
        run.append(_dwell_block(0, *DWELLS[0]))
        run.add_point(PointAttempt(0, 5.0, 2.0, 0, 500, 2500, 3000))
    run.append(_dwell_block(3000, *DWELLS[1]))
    run.add_point(PointAttempt(1, 12.5, 2.0, 3000, 3500, 5500, 6000))
    run.finish("complete")
    with pytest.raises(StoreError, match="resumed already"):
        writer.continue_run("001-grid")
    writer.close()

    with open_campaign(path) as f:
        old, new = f.runs
        assert (old.status, old.resumed_by, new.resumes) == ("incomplete", "002-grid", "001-grid")
        assert new.completed_point_indices() == {0, 1}
        records = new.dwell_records()
        assert [r.freq_hz for r in records] == [5.0, 12.5]
        np.testing.assert_array_equal(records[0].channels["sample"], np.arange(3000))


def test_writer_refuses_bad_blocks_and_rows_naming_the_place(campaign):
    path, writer = campaign
    run = writer.begin_run(
        "r1", kind="sweep", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
    )
    block = _dwell_block(0, 5.0, 1.0)
    with pytest.raises(StoreError, match=r"/runs/r1/channels: block channels differ: missing \['status'\]"):
        run.append({k: v for k, v in block.items() if k != "status"})
    with pytest.raises(StoreError, match=r"/runs/r1/channels/sample: uint32 channel given float64"):
        run.append(block | {"sample": block["sample"].astype(float)})
    with pytest.raises(StoreError, match=r"/runs/r1/channels/status: values -1..-1 outside uint16"):
        run.append(block | {"status": np.full(3000, -1)})
    with pytest.raises(StoreError, match="different lengths"):
        run.append(block | {"status": block["status"][:10]})
    assert run.samples == 0
    run.append(block)
    with pytest.raises(
        StoreError, match=r"/runs/r1/points: point 0: samples start 0 .* recorded 3000 do not hold"
    ):
        run.add_point(PointAttempt(0, 5.0, 1.0, 0, 10, 20, 3001))
    with pytest.raises(StoreError, match="still being written"):
        writer.begin_run("r2", kind="sweep", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ)
    run.finish("aborted", "operator abort")
    with pytest.raises(StoreError, match="is finished"):
        run.append(block)
    with pytest.raises(StoreError, match="kind 'dwell'"):
        writer.begin_run("r2", kind="dwell", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ)
    with pytest.raises(StoreError, match="channel names repeat"):
        writer.begin_run(
            "r2", kind="sweep", step={}, conditions={}, channels=CHANNELS * 2, sample_rate_hz=FS_HZ
        )
    writer.close()
    with pytest.raises(StoreError, match="exists already"):
        CampaignWriter.create(path, software_version="x", config_toml="", sequence_toml="", sequence_name="")
    with open_campaign(path) as f:
        assert (f.runs[0].status, f.runs[0].reason) == ("aborted", "operator abort")


def test_sweep_and_hammer_records_take_their_point_and_step(campaign):
    path, writer = campaign
    sweep = {"type": "sweep", "start_hz": 0.1, "end_hz": 30.0, "duration_s": 3.0, "amplitude_mm": 2.0}
    run = writer.begin_run(
        "s", kind="sweep", step=sweep, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
    )
    run.append(_dwell_block(0, 1.0, 2.0))
    run.append(_dwell_block(3000, 1.0, 2.0))
    run.add_point(PointAttempt(0, math.nan, 2.0, 1000, 1000, 4000, 4000))
    run.finish("complete")
    hammer_channels = (Channel("fz_wfs_n", "N"), Channel("f_hammer_n", "N"))
    run = writer.begin_run(
        "h",
        kind="hammer",
        step={"type": "hammer"},
        conditions={},
        channels=hammer_channels,
        sample_rate_hz=10_000.0,
    )
    ring = np.exp(-np.arange(3000) / 300.0) * np.sin(2 * np.pi * 2200 * np.arange(3000) / 1e4)
    run.append({"fz_wfs_n": ring, "f_hammer_n": np.zeros(3000)})
    run.add_point(PointAttempt(0, math.nan, math.nan, 0, 0, 3000, 3000))
    run.finish("complete")
    writer.close()

    with open_campaign(path) as f:
        rec = f.run("s").sweep_record()
        assert (rec.start_hz, rec.end_hz, rec.sweep_s, rec.amplitude_m, rec.sample_rate_hz) == (
            0.1,
            30.0,
            3.0,
            2e-3,
            FS_HZ,
        )
        np.testing.assert_array_equal(rec.channels["sample"], np.arange(1000, 4000))
        hammer = f.run("h").hammer_record()
        assert hammer.sample_rate_hz == 10_000.0
        np.testing.assert_array_equal(hammer.channels["fz_wfs_n"], ring.astype(np.float32))
        with pytest.raises(StoreError, match=r"/runs/h@kind: a hammer run has no dwell records"):
            f.run("h").dwell_records()
        with pytest.raises(StoreError, match=r"/runs/h/points: no done point 1"):
            f.run("h").hammer_record(1)


def test_file_is_versioned_and_bounded_for_hdf5_1_10(campaign):
    path, writer = campaign
    writer.close()
    with h5py.File(path, "r") as f:
        assert (f.attrs["schema"], f.attrs["schema_version"]) == (SCHEMA_NAME, SCHEMA_VERSION)
        assert f.id.get_create_plist().get_version()[0] == 2  # superblock v2: no open-for-write flag


class SimulatedClock:
    """Wall seconds that advance only when the test says so."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def test_flush_cadence_is_one_second_of_samples_or_of_wall_time(tmp_path):
    clock = SimulatedClock()
    writer = CampaignWriter.create(
        tmp_path / "c.h5",
        software_version="",
        config_toml="",
        sequence_toml="",
        sequence_name="",
        clock=clock,
    )
    run = writer.begin_run(
        "r", kind="sweep", step={}, conditions={}, channels=CHANNELS[1:2], sample_rate_hz=FS_HZ
    )
    run.append({"z_base_m": np.zeros(999)})
    assert (run.samples, run.durable_samples) == (999, 0)
    run.append({"z_base_m": np.zeros(1)})  # one second of samples: flushed
    assert run.durable_samples == 1000
    run.append({"z_base_m": np.zeros(10)})
    run.add_point(PointAttempt(0, 1.0, 1.0, 0, 0, 1010, 1010))
    clock.now_s = 0.999
    assert not writer.flush_if_due()
    clock.now_s = 1.0  # one second of wall time: flushed, but a partial chunk waits for the run's end
    assert writer.flush_if_due()
    assert run.durable_samples == 1000
    run.add_event("state", "paused")  # any write checks the cadence
    clock.now_s = 2.5
    run.add_event("state", "running")
    assert run.durable_samples == 1000
    run.append({"z_base_m": np.zeros(990)})  # the second chunk is full
    assert run.durable_samples == 2000
    run.append({"z_base_m": np.zeros(5)})
    run.finish("complete")  # the last partial chunk
    assert run.durable_samples == 2005
    writer.close()
    with open_campaign(tmp_path / "c.h5") as f:
        (view,) = f.runs
        assert (view.n_samples, [p.end_sample for p in view.points]) == (2005, [1010])
        assert [e.text for e in view.events] == ["paused", "running"]


def test_a_continued_run_that_resumes_another_keeps_the_whole_chain_once(campaign):
    path, writer = campaign
    run = writer.begin_run(
        "a", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
    )
    run.append(_dwell_block(0, *DWELLS[0]))
    run.add_point(PointAttempt(0, 5.0, 2.0, 0, 500, 2500, 3000))
    writer.close()
    with CampaignWriter.open_append(path) as writer:
        run = writer.begin_run(
            "b",
            kind="dwell_grid",
            step={},
            conditions={},
            channels=CHANNELS,
            sample_rate_hz=FS_HZ,
            resumes="a",
        )
        run.append(_dwell_block(0, *DWELLS[1]))
        run.add_point(PointAttempt(1, 12.5, 2.0, 0, 500, 2500, 3000))
    with CampaignWriter.open_append(path) as writer:
        run = writer.continue_run("b")
        run.append(_dwell_block(3000, *DWELLS[2]))
        for index in (0, 1):  # done in "a" and in "b" before the interruption
            with pytest.raises(StoreError, match=f"point {index} is done already"):
                run.add_point(PointAttempt(index, 31.0, 1.0, 3000, 3500, 5500, 6000))
        run.add_point(PointAttempt(2, 31.0, 1.0, 3000, 3500, 5500, 6000))
        run.finish("complete")
    with open_campaign(path) as f:
        assert f.run("b").completed_point_indices() == {0, 1, 2}
        assert [r.freq_hz for r in f.run("b").dwell_records()] == [5.0, 12.5, 31.0]


def test_a_block_is_copied_so_the_caller_may_reuse_its_buffer(campaign):
    path, writer = campaign
    run = writer.begin_run(
        "r", kind="sweep", step={}, conditions={}, channels=CHANNELS[1:2], sample_rate_hz=FS_HZ
    )
    buffer = np.arange(10, dtype=np.float32)
    run.append({"z_base_m": buffer})
    buffer[:] = -1.0  # the acquisition refills its buffer before the writer flushes
    run.finish("complete")
    writer.close()
    with open_campaign(path) as f:
        np.testing.assert_array_equal(f.runs[0].channels["z_base_m"], np.arange(10, dtype=np.float32))
