"""A sequence that fails marks its run ``failed`` with the reason (docs/hdf5.md: ``incomplete`` is
kept for a writer that died), on the simulated lab over the real transports: a WFS that does not
answer TARE, before the run's stream starts (no sample recorded yet) and before the first run."""

from __future__ import annotations

from bench.store import open_campaign
from tests.campaign_lab import bench_config, grid_sequence, lab_campaign


def _campaign_events(path):
    with open_campaign(path) as campaign:
        return [(e.kind, e.text) for e in campaign.events]


def test_no_reply_to_tare_before_the_stream_marks_the_run_failed_with_the_reason(tmp_path):
    config = bench_config(tmp_path, '[calibration]\ntare = "before_each_run"\n')
    path = tmp_path / "campaign.h5"
    with lab_campaign(config, grid_sequence((10.0,)), path) as campaign:
        campaign.lab.device.ignored_commands.add("TARE")
        campaign.start()
        outcome = campaign.wait()
    assert outcome.status == "failed"
    assert "TARE" in outcome.reason
    with open_campaign(path) as campaign:
        (run,) = campaign.runs
        assert run.status == "failed"
        assert run.reason == outcome.reason  # "link error: no reply to 'TARE' within 1.0 s; ..."
        assert run.finished
        assert run.n_samples == 0  # it failed before its first sample
    assert ("sequence finished", outcome.reason) in _campaign_events(path)


def test_no_reply_to_a_tare_before_any_run_is_the_sequence_s_reason(tmp_path):
    """Tared once at the sequence's start: no run began, so none is in the file; the campaign's
    events say the sequence failed and why."""
    config = bench_config(tmp_path, '[calibration]\ntare = "once"\n')
    path = tmp_path / "campaign.h5"
    with lab_campaign(config, grid_sequence((10.0,)), path) as campaign:
        campaign.lab.device.ignored_commands.add("TARE")
        campaign.start()
        outcome = campaign.wait()
    assert outcome.status == "failed" and "TARE" in outcome.reason
    with open_campaign(path) as campaign:
        assert not campaign.runs
    assert ("sequence finished", outcome.reason) in _campaign_events(path)
