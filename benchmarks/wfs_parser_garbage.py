"""WFS stream parser throughput through every kind of garbage, against the 921600-baud line rate.

Kinds: each byte value 0..255 repeated; sync words (back to back, shifted by one, one every 3 bytes,
one every 64 bytes before random bytes, a sync word then random bytes); capture sync words (back to
back, one every 24 bytes before random bytes); ``$`` bytes and ``$`` lines that never end or are too
long; random bytes; and mixes: real frames alternating with bursts of garbage of each kind. Each is
parsed in 4 KiB reads and in 64 KiB reads (the reader's sizes on a pty and at most), each figure the
best of ``--repeats``. Baseline in the same run: clean back-to-back frames parsed in the same reads.

Figures: MB/s, the ratio to the line's 92.16 kB/s (8N1: 10 bits per byte; target >= 10x on every
kind) and the ratio to the clean-frame baseline.

Run: PYTHONPATH=. .venv/bin/python benchmarks/wfs_parser_garbage.py [--bytes N] [--repeats N]
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.timing import best_time_s
from drivers.wfs_capture import CAPTURE_SYNC_BYTES
from drivers.wfs_frame import FRAME_SIZE, SYNC_BYTES, encode, new_frames
from drivers.wfs_stream import StreamParser

LINE_BYTES_S = 921600 / 10
READ_SIZES = (4096, 65536)
TARGET = 10.0


def _frames(n: int) -> bytes:
    f = new_frames(n)
    f["seq"] = np.arange(n)
    f["sample"] = np.arange(n)
    f["boot"] = 1
    f["fz"] = np.random.default_rng(0).normal(0, 100, n)
    return encode(f)


def _tile(piece: bytes, size: int) -> bytes:
    return (piece * (size // len(piece) + 1))[:size]


def _random(rng: np.random.Generator, n: int) -> bytes:
    return rng.integers(0, 256, n, np.uint8).tobytes()


def garbage_kinds(size: int) -> dict[str, bytes]:
    """Every kind of garbage but the single byte values, about ``size`` bytes each."""
    rng = np.random.default_rng(1)
    every_64 = b"".join(SYNC_BYTES + _random(rng, 62) for _ in range(size // 64))
    sync_random = b"".join(SYNC_BYTES + _random(rng, int(rng.integers(0, 8))) for _ in range(size // 5))
    capture_24 = b"".join(CAPTURE_SYNC_BYTES + _random(rng, 22) for _ in range(size // 24))
    kinds = {
        "sync words back to back": _tile(SYNC_BYTES, size),
        "sync words shifted by one": _tile(SYNC_BYTES[::-1], size),
        "a sync word every 3 bytes": _tile(SYNC_BYTES + b"\x00", size),
        "a sync word every 64 bytes, random between": every_64,
        "sync words with 0-7 random bytes between": sync_random[:size],
        "capture sync words back to back": _tile(CAPTURE_SYNC_BYTES, size),
        "a capture sync word every 24 bytes, random between": capture_24,
        "$ bytes": _tile(b"$", size),
        "$ lines never ended": _tile(b"$OK,STOP,", size),
        "$ lines too long": _tile(b"$" + b"A" * 200, size),
        "$ lines with a bad checksum": _tile(b"$OK,STOP*00\r\n", size),
        "random bytes": _random(rng, size),
    }
    frames = _frames(size // 128)
    mixes = {}
    for name in ("sync words back to back", "capture sync words back to back", "$ bytes", "random bytes"):
        burst = kinds[name][:64]
        pieces = [frames[i : i + FRAME_SIZE] + burst for i in range(0, len(frames), FRAME_SIZE)]
        mixes[f"mix: a frame, 64 bytes of {name}"] = b"".join(pieces)[:size]
    names = list(kinds)
    every_mix = b"".join(
        frames[i : i + FRAME_SIZE] + kinds[names[int(rng.integers(len(names)))]][: int(rng.integers(1, 200))]
        for i in range(0, len(frames), FRAME_SIZE)
    )
    mixes["mix: a frame, 1-199 bytes of any kind"] = every_mix[:size]
    return kinds | mixes


def _parse(data: bytes, read_size: int) -> StreamParser:
    parser = StreamParser()
    for i in range(0, len(data), read_size):
        parser.feed(data[i : i + read_size])
    return parser


def _rate(data: bytes, read_size: int, repeats: int) -> float:
    return len(data) / best_time_s(lambda: _parse(data, read_size), repeats=repeats)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--bytes", type=int, default=1 << 20, help="bytes per kind (byte values: a quarter)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    clean = _frames(args.bytes // FRAME_SIZE)
    baseline = {r: _rate(clean, r, args.repeats) for r in READ_SIZES}
    print(f"line: {LINE_BYTES_S / 1e3:.2f} kB/s (921600 baud, 8N1); target >= {TARGET:g}x on every kind")
    head = "".join(f" | {r // 1024} KiB reads: MB/s, x line, x baseline" for r in READ_SIZES)
    print(f"{'kind':57}{head}")

    def row(name: str, rates: dict[int, float]) -> None:
        cells = "".join(
            f" | {rates[r] / 1e6:8.2f} {rates[r] / LINE_BYTES_S:8.1f}x {rates[r] / baseline[r]:6.2f}"
            for r in READ_SIZES
        )
        print(f"{name:57}{cells}")

    row("baseline: clean frames", baseline)
    worst: dict[int, tuple[float, str]] = {r: (float("inf"), "") for r in READ_SIZES}
    byte_rates = {r: [] for r in READ_SIZES}
    for value in range(256):
        data = bytes([value]) * (args.bytes // 4)
        for r in READ_SIZES:
            rate = _rate(data, r, max(1, args.repeats - 1))
            byte_rates[r].append(rate)
            worst[r] = min(worst[r], (rate, f"byte 0x{value:02X} repeated"))
    for r in READ_SIZES:
        rates = np.array(byte_rates[r])
        slowest = int(np.argmin(rates))
        print(
            f"each byte value 0x00-0xFF repeated, {r // 1024} KiB reads: slowest 0x{slowest:02X} "
            f"{rates[slowest] / LINE_BYTES_S:.1f}x line, median {np.median(rates) / LINE_BYTES_S:.1f}x, "
            f"fastest {rates.max() / LINE_BYTES_S:.1f}x"
        )
    for value in (0x00, 0x24, 0x3C, 0x5A, 0xA5, 0xC3, 0xFF):
        row(f"byte 0x{value:02X} repeated", {r: byte_rates[r][value] for r in READ_SIZES})
    for name, data in garbage_kinds(args.bytes).items():
        rates = {r: _rate(data, r, args.repeats) for r in READ_SIZES}
        row(name, rates)
        for r in READ_SIZES:
            worst[r] = min(worst[r], (rates[r], name))
    for r in READ_SIZES:
        rate, name = worst[r]
        verdict = "met" if rate / LINE_BYTES_S >= TARGET else "NOT met"
        print(f"slowest kind, {r // 1024} KiB reads: {name}: {rate / LINE_BYTES_S:.1f}x the line ({verdict})")


if __name__ == "__main__":
    main()
