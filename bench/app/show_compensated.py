"""``wfsbench show FILE`` of a compensated force (the output of ``wfsbench compensate``): what it
was made from and with which assumptions, and what it holds, read without changing a byte of it.

:func:`compensated_summary` gathers it as one JSON-ready mapping (schema ``wfs-bench-show-compensated``,
version :data:`VERSION`, docs/cli.md): the file's origin (the campaign, its analysis, the measurement,
the software), the identification used, the chain stated or assumed and where each came from, the
valid band, and the samples: how many are defined, the force's mean, rms about it and extremes,
the band's mean and largest half-width (read block by block: the memory taken does not grow with
the record).
:func:`compensated_lines` words it for a person.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bench.analysis.blockwise import Moments
from bench.app.show import finite_or_none
from bench.store.compensated import open_compensated

SCHEMA = "wfs-bench-show-compensated"
#: Version 1 only gains keys; renaming or removing one, or changing its meaning, makes version 2.
VERSION = 1
#: The root attributes shown as they are, in this order (docs/compensate.md, *The output*).
SHOWN = (
    "software_version",
    "created",
    "campaign",
    "campaign_analysis",
    "measurement",
    "identification",
    "tyre_pressure_bar",
    "identified_pressure_bar",
    "valid_band_hz",
    "verified_band_hz",
    "hub_lag_ms",
    "bandwidth_hz",
    "noise_wfs_n",
    "noise_accel_m_s2",
    "n_taps",
    "latency_samples",
)


def compensated_summary(path: str | Path) -> dict[str, Any]:
    """What the compensated force file at ``path`` holds (module docstring);
    :class:`~bench.store.compensated.CompensatedFileError` naming the file when it is none."""
    with open_compensated(path) as compensated:
        attributes = compensated.attributes
        force, band, times = Moments(), Moments(), []
        for block in compensated.blocks():
            defined = np.isfinite(block["f_contact_n"]) & np.isfinite(block["u95_n"])
            force.add(block["f_contact_n"][defined].astype(float))
            band.add(block["u95_n"][defined].astype(float))
            times += [float(block["t_s"][0]), float(block["t_s"][-1])]
        n, defined_n = compensated.n_samples, force.count
        return {
            "schema": SCHEMA,
            "version": VERSION,
            "file": str(compensated.path),
            "schema_version": attributes.get("schema_version"),
            **{key: finite_or_none(attributes.get(key)) for key in SHOWN},
            "sources": {
                key.removesuffix("_source"): value
                for key, value in attributes.items()
                if key.endswith("_source")
            },
            "assumptions": [line for line in str(attributes.get("assumptions", "")).splitlines() if line],
            "samples": {
                "n": n,
                "sample_rate_hz": compensated.sample_rate_hz,
                "first_s": times[0] if times else None,
                "last_s": times[-1] if times else None,
                "defined": defined_n,
                "f_contact_mean_n": force.mean if defined_n else None,
                "f_contact_rms_n": force.std if defined_n else None,
                "f_contact_min_n": force.minimum if defined_n else None,
                "f_contact_max_n": force.maximum if defined_n else None,
                "u95_mean_n": band.mean if defined_n else None,
                "u95_max_n": band.maximum if defined_n else None,
            },
        }


def _band(band: list[float] | None) -> str:
    return "none" if band is None else f"{band[0]:.4g}-{band[1]:.4g} Hz"


def compensated_lines(summary: dict[str, Any]) -> list[str]:
    """The summary as text: the file and what made it, the chain, the band, the samples."""
    samples = summary["samples"]
    lines = [
        f"{summary['file']}: compensated force, schema version {summary['schema_version']}, written by"
        f" wfs-bench {summary['software_version']}, created {summary['created']}",
        f"measurement: {summary['measurement']}",
        f"campaign: {summary['campaign']} ({summary['campaign_analysis']})",
        f"identification: {summary['identification']}",
        f"valid band {_band(summary['valid_band_hz'])} (verified by the campaign"
        f" {_band(summary['verified_band_hz'])}); filters {summary['n_taps']} taps, latency"
        f" {summary['latency_samples']} samples",
        "assumptions:",
        *(f"  {line}" for line in summary["assumptions"]),
    ]
    span = (
        f", {samples['first_s']:.6g}-{samples['last_s']:.6g} s" if samples["first_s"] is not None else ""
    )
    rate = samples["sample_rate_hz"]
    lines.append(f"samples: {samples['n']} at {rate:g} Hz{span}; {samples['defined']} defined")
    if samples["defined"]:
        lines.append(
            f"contact force: mean {samples['f_contact_mean_n']:.4g} N, rms about it"
            f" {samples['f_contact_rms_n']:.4g} N,"
            f" {samples['f_contact_min_n']:.4g} to {samples['f_contact_max_n']:.4g} N; 95 % band half-width"
            f" {samples['u95_mean_n']:.3g} N on average, {samples['u95_max_n']:.3g} N at the most"
        )
    return lines
