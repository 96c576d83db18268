"""The compensation's filters exported for a real-time DSP (``wfsbench compensate --filters``), as
JSON or CSV (layouts in docs/compensate.md).

What a DSP needs to reproduce the command's compensated force sample by sample: the two FIR taps,
the sample rate they were designed for, the latency (the output at sample ``n`` is the contact
force at ``n - latency``), the band they are valid in, and what the inputs are (Fz in N, the hub
acceleration in m/s^2 less its offset).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from bench.analysis.measurement_compensation import CompensationFilters

FORMAT_NAME = "wfs-bench compensation filters"
FORMAT_VERSION = 1
#: The rule the taps implement, as the export states it.
RULE = (
    "F_contact[n - latency_samples] = sum_k taps_wfs[k] Fz[n - k]"
    " + sum_k taps_accel[k] (a_hub[n - k] - accelerometer_offset_m_s2)"
)


def filter_description(filters: CompensationFilters, accelerometer_offset_m_s2: float) -> dict[str, Any]:
    """Everything the export holds but the taps, as plain values."""
    basis = filters.basis
    return {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "identification": basis.label,
        "sample_rate_hz": filters.fs_hz,
        "n_taps": filters.n_taps,
        "latency_samples": filters.latency_samples,
        "latency_ms": 1e3 * filters.latency_samples / filters.fs_hz,
        "valid_band_hz": list(basis.valid_band_hz),
        "design_band_hz": basis.band_hz,
        "accelerometer_delay_s": basis.accelerometer_delay_s,
        "accelerometer_offset_m_s2": accelerometer_offset_m_s2,
        "rule": RULE,
        "inputs": {"Fz": "N, compression positive", "a_hub": "m/s^2, upward"},
        "output": "N, the contact force, compression positive",
    }


def write_filters(path: str | Path, filters: CompensationFilters, accelerometer_offset_m_s2: float) -> Path:
    """Write the filters to ``path``: JSON for ``.json``, CSV for ``.csv`` (ValueError otherwise)."""
    path = Path(path)
    info = filter_description(filters, accelerometer_offset_m_s2)
    taps_wfs = filters.compensator.taps_wfs.tolist()
    taps_accel = filters.compensator.taps_accel.tolist()
    suffix = path.suffix.lower()
    if suffix == ".json":
        path.write_text(json.dumps({**info, "taps_wfs": taps_wfs, "taps_accel": taps_accel}, indent=1) + "\n")
    elif suffix == ".csv":
        with path.open("w", newline="") as f:
            for key, value in info.items():
                shown = json.dumps(value) if isinstance(value, list | dict) else value
                f.write(f"# {key}: {shown}\n")
            writer = csv.writer(f)
            writer.writerow(["k", "taps_wfs", "taps_accel"])
            writer.writerow(["sample", "N/N", "N/(m/s^2)"])
            writer.writerows(
                (k, repr(w), repr(a)) for k, (w, a) in enumerate(zip(taps_wfs, taps_accel, strict=True))
            )
    else:
        raise ValueError(f"{path}: filters are exported as .json or .csv, not {suffix or 'no suffix'}")
    return path
