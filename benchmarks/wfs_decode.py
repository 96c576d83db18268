"""WFS frame decode throughput, as a ratio to the frame rate a 921600-baud link can carry.

Baseline (same run): a plain copy of the same bytes into a numpy array, the floor any decoder pays.
Run: python benchmarks/wfs_decode.py [--frames N]
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.timing import best_time_s
from drivers.wfs_frame import FRAME_SIZE, decode, encode, new_frames
from drivers.wfs_stream import StreamParser

LINE_RATE_FPS = 921600 / 10 / FRAME_SIZE  # 8N1: 10 bits per byte


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=200_000)
    n = parser.parse_args().frames
    frames = new_frames(n)
    frames["seq"] = np.arange(n)
    frames["fz"] = np.random.default_rng(0).normal(0, 100, n)
    data = encode(frames)
    copy_s = best_time_s(lambda: np.frombuffer(data, np.uint8).copy())
    decode_s = best_time_s(lambda: decode(data))

    def stream():
        p = StreamParser()
        for i in range(0, len(data), 4096):
            p.feed(data[i : i + 4096])

    stream_s = best_time_s(stream, repeats=3)
    print(f"line rate at 921600 baud: {LINE_RATE_FPS:.0f} frames/s")
    print(f"baseline copy           : {n / copy_s:,.0f} frames/s")
    for name, seconds in (("block decode + CRC", decode_s), ("stream parser, 4 KiB reads", stream_s)):
        fps = n / seconds
        print(f"{name:26}: {fps:,.0f} frames/s = {fps / LINE_RATE_FPS:,.0f}x line rate "
              f"({seconds / copy_s:.1f}x the copy baseline's time)")  # fmt: skip


if __name__ == "__main__":
    main()
