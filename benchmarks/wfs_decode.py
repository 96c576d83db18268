"""WFS frame decode throughput, as a ratio to the frame rate a 921600-baud link can carry, and the
stream parser's speed through the worst garbage (nothing but sync words, each a candidate frame
whose CRC fails) as a ratio to the line's byte rate.

Baseline (same run): a plain copy of the same bytes into a numpy array, the floor any decoder pays.
Run: python benchmarks/wfs_decode.py [--frames N] [--garbage-bytes N]
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.timing import best_time_s
from drivers.wfs_frame import FRAME_SIZE, SYNC_BYTES, decode, encode, new_frames
from drivers.wfs_stream import StreamParser

LINE_BYTES_S = 921600 / 10  # 8N1: 10 bits per byte
LINE_RATE_FPS = LINE_BYTES_S / FRAME_SIZE


def _feed(data: bytes, read_size: int = 4096) -> StreamParser:
    parser = StreamParser()
    for i in range(0, len(data), read_size):
        parser.feed(data[i : i + read_size])
    return parser


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--garbage-bytes", type=int, default=2_000_000)
    args = parser.parse_args()
    n = args.frames
    frames = new_frames(n)
    frames["seq"] = np.arange(n)
    frames["fz"] = np.random.default_rng(0).normal(0, 100, n)
    data = encode(frames)
    copy_s = best_time_s(lambda: np.frombuffer(data, np.uint8).copy())
    decode_s = best_time_s(lambda: decode(data))

    stream_s = best_time_s(lambda: _feed(data), repeats=3)
    print(f"line rate at 921600 baud: {LINE_RATE_FPS:.0f} frames/s")
    print(f"baseline copy           : {n / copy_s:,.0f} frames/s")
    for name, seconds in (("block decode + CRC", decode_s), ("stream parser, 4 KiB reads", stream_s)):
        fps = n / seconds
        print(f"{name:26}: {fps:,.0f} frames/s = {fps / LINE_RATE_FPS:,.0f}x line rate "
              f"({seconds / copy_s:.1f}x the copy baseline's time)")  # fmt: skip
    garbage = SYNC_BYTES * (args.garbage_bytes // 2)
    rejects = _feed(garbage).counters.crc_rejects
    garbage_s = best_time_s(lambda: _feed(garbage), repeats=3)
    garbage_copy_s = best_time_s(lambda: np.frombuffer(garbage, np.uint8).copy())
    rate = len(garbage) / garbage_s
    print(f"garbage of sync words   : {rate / 1e6:,.2f} MB/s = {rate / LINE_BYTES_S:,.1f}x the line's "
          f"{LINE_BYTES_S / 1e3:.1f} kB/s ({garbage_s / garbage_copy_s:,.0f}x the copy baseline's time, "
          f"{rejects:,} sync words rejected)")  # fmt: skip


if __name__ == "__main__":
    main()
