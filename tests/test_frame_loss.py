"""Frames lost on the WFS link never move the actuator: the simulated lab over its real transports
(the controller on Modbus TCP, the WFS on a pty), with bursts of frames lost at set places of every
hold (``simulators.wfs_device.FrameLoss``: at the hold's start, mid-way through the engine's first
amplitude window and in the hold's last cycle), placed by the frames' own hold bit so that they land
in the same place whatever the machine's speed.

For a grid corrected by repeats, a grid held within the dwell, an adaptive grid and a tracked
dwell, with bursts of 1, 10, 100, 350 and 3,000 frames:
- the plate's **true** amplitude (the plant's displacement in every block the bench made, the lost
  frames included: a bench sink beside the WFS device) never exceeds the target by more than the
  excursion tolerance (10 %);
- no command is changed on a window that missed more than ``max_missing_fraction`` (5 %) of its
  frames: every in-dwell update rests on a window with its frames, and a point measured on a lossy
  hold is repeated at the same command;
- each done point's analysed FRF (``F_wfs / F_plate``, the analysis's dwell fit on true sample
  times) equals the loss-free run's within three standard uncertainties of the difference.

The tyre is linear here, so that the FRF does not depend on the amplitude the two runs reached.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from bench.analysis.records import PLATE_FORCE, WFS_FORCE, WHEEL_CHANNELS, fit_dwell_record
from bench.engine import events as ev
from bench.engine.stops import RunOutcome
from bench.store import open_campaign
from sequences import AdaptiveDwell, DwellGrid, Hydraulics, Sequence, TrackedDwell
from simulators.bench_sim import BenchBlock
from simulators.wfs_device import FrameLoss
from tests.campaign_lab import PACED_IN_PROCESS, bench_config, grid_sequence, lab_campaign

AMPLITUDE_MM = 1.0
#: A linear tyre; and host stalls of up to 4 s lose nothing on these links (the device holds 5 s of
#: frames for its host: unpaced by default, paced with flow control in :data:`PACED_IN_PROCESS`): a
#: stall of the loaded machine's own (1.2 s seen beside four busy processes) that happened to come
#: just before an injected burst would otherwise be credited with the burst's frames and end the run
#: as a host stall.
LINEAR = "[specimen]\nnonlinear = false\n[timing]\nhost_stall_s = 4.0\n"
BY_REPEATS = LINEAR + "[amplitude]\nhold_within_dwell = false\n"
#: The grids' frequencies: below, at and above the tread resonance's rise; 16 Hz is where the plate
#: went to 1.71 mm behind a lossy link.
FREQS_HZ = (16.0, 36.0)
#: A grid dwell's hold (grid_sequence: 2 settle cycles, at least 0.1 s; measured 0.5 s at least).
HOLD_FRAMES = 600
MISSING_ALLOWED = 0.05


def bursts_of(
    frames: int, hold_frames: int = HOLD_FRAMES, holds: tuple[int, ...] | None = None
) -> tuple[FrameLoss, ...]:
    """Bursts of ``frames`` at the start of a hold, mid-way through its first window (4 cycles of
    36 Hz, 0.11 s) and in its last cycle: in every hold, or in those numbered ``holds``."""
    return tuple(FrameLoss(at, frames, holds) for at in (0, 50, hold_frames - 30))


EXCURSION = 0.10


#: Bursts of each size: small ones in every hold (a link that keeps losing frames), large ones in the
#: run's first hold (a burst of 3,000 frames swallows a hold and what follows it).
LOSSES = {
    "1 in every hold": bursts_of(1),
    "10 in every hold": bursts_of(10),
    "100 in the first hold": bursts_of(100, holds=(0,)),
    "350 in the first hold": bursts_of(350, holds=(0,)),
    "3000 in the first hold": bursts_of(3000, holds=(0,)),
}


class TruePlate:
    """A bench sink beside the WFS device: the largest displacement the plant made (m), lost frames
    included (it never paces the bench)."""

    paces_bench = False

    def __init__(self) -> None:
        self.peak_m = 0.0

    def deliver(self, block: BenchBlock) -> None:
        self.peak_m = max(self.peak_m, float(np.max(np.abs(block.channels["z_base_m"]))))


def adaptive_sequence() -> Sequence:
    plan = AdaptiveDwell(plate_mass_kg=12.0, min_hold_cycles=2, max_added_points=0, max_hold_s=3.0)
    grid = DwellGrid(
        freqs_hz=FREQS_HZ, amplitudes_mm=(AMPLITUDE_MM,), taper_in_s=0.2, taper_out_s=0.2, adaptive=plan
    )
    return Sequence("adaptive", "", (Hydraulics("low"), Hydraulics("high"), grid), "<test>")


def tracked_sequence() -> Sequence:
    step = TrackedDwell(
        30.0, 46.0, AMPLITUDE_MM, search_points=5, plate_mass_kg=12.0, track_s=1.5, freq_band_pct=10.0,
        taper_in_s=0.2, taper_out_s=0.2,
    )  # fmt: skip
    return Sequence("track", "", (Hydraulics("low"), Hydraulics("high"), step), "<test>")


#: In real time, as a lab's bench runs (no frame lost but what the test loses on purpose).
PACED = PACED_IN_PROCESS
KINDS = {
    "grid by repeats": (BY_REPEATS, lambda: grid_sequence(FREQS_HZ, AMPLITUDE_MM)),
    "held grid": (LINEAR, lambda: grid_sequence(FREQS_HZ, AMPLITUDE_MM)),
    "paced held grid": (LINEAR + PACED, lambda: grid_sequence(FREQS_HZ, AMPLITUDE_MM)),
    "adaptive grid": (LINEAR, adaptive_sequence),
    "paced adaptive grid": (LINEAR + PACED, adaptive_sequence),
    "tracked dwell": (LINEAR, tracked_sequence),
    "paced tracked dwell": (LINEAR + PACED, tracked_sequence),
}


def run(
    folder: Path, kind: str, losses: tuple[FrameLoss, ...]
) -> tuple[Path, list[ev.Event], TruePlate, RunOutcome]:
    config_text, sequence = KINDS[kind]
    path = folder / "campaign.h5"
    plate = TruePlate()
    with lab_campaign(bench_config(folder, config_text), sequence(), path) as campaign:
        campaign.lab.device.frame_losses = losses
        campaign.lab.runner.sinks.append(plate)
        campaign.start()
        outcome = campaign.wait()
    return path, campaign.events, plate, outcome


@pytest.fixture(scope="module")
def loss_free(tmp_path_factory):
    """The loss-free run of each kind, run once for the module (by kind, when first asked)."""
    runs: dict[str, tuple[Path, list[ev.Event], TruePlate, str]] = {}

    def of(kind: str):
        if kind not in runs:
            runs[kind] = run(tmp_path_factory.mktemp("reference"), kind, ())
            assert runs[kind][3].status == "complete", (kind, runs[kind][3])
        return runs[kind]

    return of


def dwell_frfs(path: Path) -> dict[float, tuple[complex, float]]:
    """Each done dwell's analysed ``F_wfs / F_plate`` and its standard uncertainty, by frequency."""
    with open_campaign(path) as campaign:
        (run_view,) = campaign.runs
        records = run_view.dwell_records()
    return {r.freq_hz: fit_dwell_record(r, WHEEL_CHANNELS).ratio(WFS_FORCE, PLATE_FORCE) for r in records}


def check_frfs_equal(reference: Path, lossy: Path) -> None:
    """Every done dwell's FRF of ``lossy`` equals ``reference``'s within three standard
    uncertainties of their difference (and 0.1 % of its value)."""
    expected = dwell_frfs(reference)
    for freq_hz, (h, sigma) in dwell_frfs(lossy).items():
        assert freq_hz in expected, f"the loss-free run did not measure {freq_hz} Hz: {sorted(expected)}"
        h0, sigma0 = expected[freq_hz]
        assert abs(h - h0) <= 3 * math.hypot(sigma, sigma0) + 1e-3 * abs(h0), (freq_hz, h, h0)


def check_no_decision_on_lossy_windows(events: list[ev.Event]) -> None:
    for look in (e for e in events if isinstance(e, ev.AmplitudeChecked)):
        if math.isfinite(look.updated_mm):  # an update was sent: on a window with its frames
            assert not look.lost, look.text
    attempts: dict[int, list[ev.PointDone]] = {}
    for done in (e for e in events if isinstance(e, ev.PointDone)):
        attempts.setdefault(done.index, []).append(done)
    for tries in attempts.values():
        for before, after in itertools.pairwise(tries):
            if "measured again at the same command" in before.note:  # the command at its hold's end
                in_force = (
                    before.held_amplitude_mm if before.amplitude_updates else before.commanded_amplitude_mm
                )
                assert after.commanded_amplitude_mm == in_force


@pytest.mark.parametrize(
    ("kind", "losses"),
    [
        *((kind, losses) for kind in ("grid by repeats", "held grid") for losses in LOSSES),
        pytest.param("paced held grid", "10 in every hold", marks=pytest.mark.validation),
        pytest.param("paced held grid", "350 in the first hold", marks=pytest.mark.validation),
    ],
)
def test_bursts_lost_in_the_holds_of_a_grid_never_move_the_command(tmp_path, loss_free, kind, losses):
    path, events, plate, outcome = run(tmp_path, kind, LOSSES[losses])
    assert outcome.status == "complete", outcome
    assert plate.peak_m <= (1 + EXCURSION) * AMPLITUDE_MM * 1e-3, plate.peak_m
    check_no_decision_on_lossy_windows(events)
    assert not [e for e in events if isinstance(e, ev.LimitReached)]
    done = [e for e in events if isinstance(e, ev.PointDone) and e.status == "done"]
    assert sorted(p.freq_hz for p in done) == sorted(FREQS_HZ)
    with open_campaign(path) as campaign:  # each hold's lost frames in the points table, as the gaps say
        (run_view,) = campaign.runs
        gaps = [(e.sample, e.fields["missing"]) for e in run_view.events if e.kind == "gap"]
        for p in run_view.points:
            in_hold = sum(m for at, m in gaps if p.hold_start_sample <= at <= p.hold_end_sample)
            assert p.frames_missing == in_hold, p
    assert sum(m for _, m in gaps) > 0
    check_frfs_equal(loss_free(kind)[0], path)


@pytest.mark.parametrize(
    ("kind", "losses"),
    [
        ("adaptive grid", "10 in every hold"),
        ("adaptive grid", "350 in the first hold"),
        ("adaptive grid", "3000 in the first hold"),
        pytest.param("paced adaptive grid", "350 in the first hold", marks=pytest.mark.validation),
    ],
)
def test_bursts_lost_in_an_adaptive_grid_wait_for_windows_with_their_frames(
    tmp_path, loss_free, kind, losses
):
    path, events, plate, outcome = run(tmp_path, kind, LOSSES[losses])
    assert outcome.status == "complete", outcome
    assert plate.peak_m <= (1 + EXCURSION) * AMPLITUDE_MM * 1e-3
    check_no_decision_on_lossy_windows(events)
    check_frfs_equal(loss_free(kind)[0], path)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("kind", "holds"),
    [
        ("tracked dwell", None),
        ("tracked dwell", (5,)),
        pytest.param("paced tracked dwell", (5,), marks=pytest.mark.validation),
    ],
    ids=["10 in every hold", "350 in the track's first hold", "paced, 350 in the track's first hold"],
)
def test_bursts_lost_in_a_track_move_the_drive_only_on_windows_with_their_frames(
    tmp_path, loss_free, kind, holds
):
    """The search's five dwells are holds 0-4, the track's first hold is hold 5. The track's looks
    that lost frames are passed over, and the resonance it finds is the loss-free track's within 1 %."""
    losses = bursts_of(10 if holds is None else 350, hold_frames=1500, holds=holds)
    path, events, plate, outcome = run(tmp_path, kind, losses)
    assert outcome.status == "complete", outcome
    assert plate.peak_m <= (1 + EXCURSION) * AMPLITUDE_MM * 1e-3
    looks = [e for e in events if isinstance(e, ev.ResonanceTracked)]
    with open_campaign(path) as campaign:  # the looks' times count the frames lost before them
        (run_view,) = campaign.runs
        lost_before = [
            sum(e.fields["missing"] for e in run_view.events if e.kind == "gap" and e.sample < look.sample)
            for look in looks
        ]
        times_s = run_view.track_record().time_s
    assert np.allclose(times_s, (np.array([look.sample for look in looks]) + lost_before) / 1000.0)
    reference = [e for e in loss_free(kind)[1] if isinstance(e, ev.ResonanceTracked)]
    assert looks and reference
    assert (
        abs(np.median([e.resonance_hz for e in looks]) / np.median([e.resonance_hz for e in reference]) - 1)
        < 0.01
    )


def test_show_and_analyze_say_what_the_link_lost(tmp_path):
    """``wfsbench show`` and the analysis name the frames the run lost and where they are recorded."""
    from bench.app.analyze import analyze_campaign
    from bench.app.show import campaign_summary, summary_lines

    path, _, _, outcome = run(tmp_path, "grid by repeats", LOSSES["350 in the first hold"])
    assert outcome.status == "complete", outcome
    summary = campaign_summary(path)
    (grid,) = summary["runs"]
    lost = grid["frames_lost"]
    assert lost >= 350 and grid["gaps"] >= 1
    text = "\n".join(summary_lines(summary))
    assert f"    {lost} frames lost on the WFS link in {grid['gaps']} gap" in text
    (analysed,) = analyze_campaign(path).runs
    assert any(f"{lost} frames lost on the WFS link" in line for line in analysed.lines), analysed.lines
