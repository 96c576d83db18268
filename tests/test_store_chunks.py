"""The writer compresses a channel's chunks itself and hands them to HDF5 finished: every stored
chunk must be, byte for byte and filter mask for filter mask, what HDF5's own filter pipeline
stores for the same samples; h5dump must read it; the file is fsync'd on the documented cadence.

The reference is a dataset created with the very creation properties of the writer's dataset and
written by HDF5 through its pipeline, in one go.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.store import CampaignWriter, StoreError, open_campaign
from sequences.channels import Channel

FS_HZ = 1000.0  # chunks of 1000 samples with the default flush interval of 1 s
CHANNELS = (
    Channel("sample", "1", "acquisition sample index", "u4"),
    Channel("fz_wfs_n", "N", "vertical WFS force", "f4"),
    Channel("status", "1", "frame status bits", "u2"),
    Channel("noise", "1", "white noise: gzip makes its chunks longer", "u4"),
)


def signals(n: int) -> dict[str, np.ndarray]:
    """Seeded columns: a counter, a noisy sine, sparse status bits, incompressible noise."""
    rng = np.random.default_rng(7)
    i = np.arange(n)
    return {
        "sample": i.astype(np.uint32),
        "fz_wfs_n": 2e3 * np.sin(2 * np.pi * 12.5 * i / FS_HZ) + rng.normal(0.0, 0.5, n),  # float64 given
        "status": (i // 700 % 4).astype(np.uint16),
        "noise": rng.integers(0, 2**32, n, dtype=np.uint32),
    }


def new_writer(path: Path, **kwargs) -> CampaignWriter:
    return CampaignWriter.create(
        path, software_version="test", config_toml="", sequence_toml="", sequence_name="", **kwargs
    )


def begin(writer: CampaignWriter):
    """Begin the run ``r`` of :data:`CHANNELS`."""
    return writer.begin_run(
        "r", kind="sweep", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
    )


def append_in_blocks(run, columns: dict[str, np.ndarray], start: int, sizes: list[int]) -> int:
    """Append ``columns[start:]`` in blocks of ``sizes`` (cycled) to the end; returns the end."""
    n = len(columns["sample"])
    k = 0
    while start < n:
        stop = min(n, start + sizes[k % len(sizes)])
        run.append({name: values[start:stop] for name, values in columns.items()})
        start, k = stop, k + 1
    return start


def assert_chunks_as_hdf5_stores_them(path: Path, run_id: str, columns: dict[str, np.ndarray]) -> None:
    """Every chunk of every channel of ``run_id`` equals HDF5's own for the same samples (bytes and
    filter mask)."""
    with h5py.File(path, "r") as f, h5py.File(path.with_suffix(".ref.h5"), "w") as ref:
        for name, values in columns.items():
            ds = f[f"/runs/{run_id}/channels/{name}"]
            assert ds.shape == values.shape
            space = h5py.h5s.create_simple(values.shape, (h5py.h5s.UNLIMITED,))
            h5py.h5d.create(ref.id, name.encode(), ds.id.get_type(), space, dcpl=ds.id.get_create_plist())
            ref[name][...] = values.astype(ds.dtype)
            ref.flush()
            np.testing.assert_array_equal(ds[()], ref[name][()], err_msg=name)
            for offset in range(0, values.shape[0], ds.chunks[0]):
                mine, theirs = ds.id.read_direct_chunk((offset,)), ref[name].id.read_direct_chunk((offset,))
                assert mine == theirs, f"{name}: chunk at {offset} differs from HDF5's"


def test_every_chunk_is_what_hdf5s_filters_store_whatever_the_block_sizes(tmp_path):
    path = tmp_path / "c.h5"
    columns = signals(7350)  # seven whole chunks and a partial one
    with new_writer(path) as writer:
        run = begin(writer)
        # blocks smaller than, across and larger than a chunk (2.5 chunks grow the buffer)
        append_in_blocks(run, columns, 0, [37, 1000, 2500, 3, 613])
        run.finish("complete")
    assert_chunks_as_hdf5_stores_them(path, "r", columns)
    with open_campaign(path) as f:
        np.testing.assert_array_equal(f.run("r").channels["noise"], columns["noise"])
        np.testing.assert_array_equal(f.run("r").channels["fz_wfs_n"], columns["fz_wfs_n"].astype(np.float32))


@pytest.mark.skipif(shutil.which("h5dump") is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_h5dump_reads_whole_and_partial_chunks_of_every_dtype(tmp_path):
    path = tmp_path / "c.h5"
    columns = signals(2500)
    with new_writer(path) as writer:
        run = begin(writer)
        append_in_blocks(run, columns, 0, [100])
        run.finish("complete")
    # across the boundary of a whole and the partial chunk, inside a whole one, the end
    for name, start in (("noise", 1998), ("status", 1398), ("sample", 2497)):
        out = subprocess.run(
            ["h5dump", "-d", f"/runs/r/channels/{name}", "-s", str(start), "-c", "3", str(path)],
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
        ).stdout
        shown = ", ".join(str(v) for v in columns[name][start : start + 3])
        assert f"({start}): {shown}\n" in out, (name, out)


def test_a_run_closed_in_a_partial_chunk_is_continued_with_that_chunk_written_again_whole(tmp_path):
    path = tmp_path / "c.h5"
    columns = signals(4200)
    with new_writer(path) as writer:
        run = begin(writer)
        append_in_blocks(run, {k: v[:1500] for k, v in columns.items()}, 0, [300])
    # closed unfinished: samples 1000..1500 sit in a partial chunk
    with CampaignWriter.open_append(path) as writer:
        run = writer.continue_run("r")
        assert (run.samples, run.durable_samples) == (1500, 1500)
        append_in_blocks(run, columns, 1500, [700])
        run.finish("complete")
    assert_chunks_as_hdf5_stores_them(path, "r", columns)
    with open_campaign(path) as f:
        assert [e.kind for e in f.run("r").events] == ["resumed"]


def test_continuing_a_channel_stored_otherwise_is_refused_before_anything_changes(tmp_path):
    path = tmp_path / "c.h5"
    columns = signals(1200)
    with new_writer(path) as writer:
        run = begin(writer)
        run.append(columns)
    with h5py.File(path, "r+") as f:  # another program rewrote one channel uncompressed
        channels = f["/runs/r/channels"]
        attrs = dict(channels["status"].attrs)
        del channels["status"]
        channels.create_dataset("status", data=columns["status"], maxshape=(None,), chunks=(1000,))
        channels["status"].attrs.update(attrs)
    refusal = r"c\.h5: /runs/r/channels/status: stored with chunks \(1000,\), filters \[\]"
    with CampaignWriter.open_append(path) as writer, pytest.raises(StoreError, match=refusal):
        writer.continue_run("r")
    with open_campaign(path) as f:
        view = f.run("r")
        assert (view.status, view.events, view.n_samples) == ("incomplete", (), 1200)


class SimulatedClock:
    """Wall seconds that advance only when the test says so."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def test_chunks_flush_each_second_of_samples_fsync_at_most_once_a_second_of_wall_time(tmp_path, monkeypatch):
    synced: list[float] = []
    clock = SimulatedClock()
    real_fsync = os.fsync

    def fsync(fd: int) -> None:  # the real fsync, noted with the simulated time it ran at
        synced.append(clock.now_s)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    columns = signals(10_000)
    writer = new_writer(tmp_path / "c.h5", clock=clock)
    run = begin(writer)
    assert synced == [0.0, 0.0]  # explicit flushes (file created, run begun) always fsync
    end = 0
    for second in range(5):  # five seconds of samples within a tenth of a second of wall time
        clock.now_s = 0.02 * second
        end = append_in_blocks(run, {k: v[: end + 1000] for k, v in columns.items()}, end, [250])
        assert run.durable_samples == end  # flushed chunk by chunk (what survives a killed writer)
    assert synced == [0.0, 0.0]
    clock.now_s = 1.0  # a second of wall time since the last fsync: the next flush fsyncs
    end = append_in_blocks(run, {k: v[: end + 1000] for k, v in columns.items()}, end, [1000])
    assert (run.durable_samples, synced[2:]) == (6000, [1.0])
    run.append({k: v[end : end + 10] for k, v in columns.items()})
    clock.now_s = 1.999
    assert not writer.flush_if_due()
    clock.now_s = 2.0  # nothing new to write but a second since the last fsync
    assert writer.flush_if_due()
    assert (run.durable_samples, synced[2:]) == (6000, [1.0, 2.0])
    clock.now_s = 2.1
    run.finish("complete")  # the end of a run fsyncs
    assert (run.durable_samples, synced[2:]) == (6010, [1.0, 2.0, 2.1])
    writer.close()
    assert synced[2:] == [1.0, 2.0, 2.1, 2.1]
