"""Road measurements for the compensation job's tests and benchmark: drives of the paper's quarter
car (the campaign's car) simulated on ISO 8608 roads, written as a logger writes them, MDF4 or CSV,
with the channels under their standard names and units."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.models.benches import TyreModel
from bench.models.road import road_drive
from bench.models.setup import BenchSetup
from bench.simulated_road import simulate_road

CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)
RATE_HZ = 1000.0


def road_channels(seed: int, duration_s: float = 20.0) -> dict[str, np.ndarray]:
    """A class C road at 60 km/h under the car's corner: ``fz_wfs_n`` and ``a_hub_m_s2``."""
    drive = road_drive("C", speed_km_h=60, duration_s=duration_s, sample_rate_hz=RATE_HZ, seed=seed)
    record = simulate_road(CAR, drive, seed=1000 + seed)
    return {name: record.channels[name] for name in ("fz_wfs_n", "a_hub_m_s2")}


def write_csv(path: Path, channels: dict[str, np.ndarray]) -> Path:
    """The channels as a CSV file with a time column ``t_s`` (the reader's default layout)."""
    t_s = np.arange(channels["fz_wfs_n"].size) / RATE_HZ
    columns = np.column_stack([t_s, channels["fz_wfs_n"], channels["a_hub_m_s2"]])
    np.savetxt(path, columns, delimiter=",", header="t_s,fz_wfs_n,a_hub_m_s2", comments="", fmt="%.17g")
    return path


def write_mdf4(path: Path, channels: dict[str, np.ndarray], block: int = 1 << 16) -> Path:
    """The channels as an MDF 4 file of one channel group (asammdf), appended ``block`` samples at a
    time (a long record never lies whole in memory)."""
    from asammdf import MDF, Signal

    mdf = MDF(version="4.10")
    n = channels["fz_wfs_n"].size
    for start in range(0, n, block):
        t_s = np.arange(start, min(start + block, n)) / RATE_HZ
        fz, a = (channels[name][start : start + block] for name in ("fz_wfs_n", "a_hub_m_s2"))
        if start == 0:
            signals = [
                Signal(fz, t_s, name="fz_wfs_n", unit="N"),
                Signal(a, t_s, name="a_hub_m_s2", unit="m/s^2"),
            ]
            mdf.append(signals, common_timebase=True)
        else:
            mdf.extend(0, [(t_s, None), (fz, None), (a, None)])
    mdf.save(path, overwrite=True, compression=0)
    mdf.close()
    return path
