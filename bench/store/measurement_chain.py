"""What a measurement states of its own acquisition chain (docs/compensate.md, *The measurement's
chain*): the lag of its hub accelerometer and the bandwidth its logger passes unchanged.

A campaign characterises the bench's accelerometer (its four-post run measures the lag) and its own
acquisition; a road measurement has its own accelerometer and logger, which only the lab that made
it knows. So they are stated with the measurement (``wfsbench compensate --hub-lag-ms``,
``--bandwidth-hz``, or the ``[measurement]`` table of its mapping file), checked here the same way
wherever they are given, and never taken from the campaign unless stated so (:data:`CAMPAIGN_LAG`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: A hub accelerometer lag stated as the campaign's own: the measurement's accelerometer is the one
#: the campaign's four-post run characterised (the same car's), so the lag that run measured applies.
CAMPAIGN_LAG = "campaign"
#: The mapping file's table that states the measurement's chain, and its keys.
MAPPING_TABLE = "measurement"
HUB_LAG_KEY = "hub_lag_ms"
BANDWIDTH_KEY = "bandwidth_hz"


@dataclass(frozen=True)
class Stated:
    """A value stated for the measurement and ``where`` it was stated (``--hub-lag-ms``,
    ``map.toml: measurement.hub_lag_ms``), which every message about it names."""

    value: float | str
    where: str


@dataclass(frozen=True)
class MeasurementChain:
    """The measurement's chain as stated: ``hub_lag_ms`` (a lag in ms, or :data:`CAMPAIGN_LAG`) and
    ``bandwidth_hz`` (the frequency up to which its logger passes Fz and the hub acceleration
    unchanged, within the valid band's tolerances); None where nothing was stated."""

    hub_lag_ms: Stated | None = None
    bandwidth_hz: Stated | None = None


def hub_lag_ms(value: object) -> float | str:
    """A stated hub accelerometer lag: a finite number of ms, 0 or more, or :data:`CAMPAIGN_LAG`
    (command-line text through :func:`from_text` first).
    ValueError saying what is allowed otherwise (text, NaN, a negative lag: an accelerometer that
    reads ahead of the force)."""
    if value == CAMPAIGN_LAG:
        return CAMPAIGN_LAG
    number = _number(value)
    if number is None or number < 0:
        raise ValueError(
            f"a hub accelerometer lag is a number of ms, 0 or more, or {CAMPAIGN_LAG!r} (the accelerometer"
            f" the campaign's four-post run measured), got {value!r}"
        )
    return number


def bandwidth_hz(value: object) -> float:
    """A stated logger bandwidth: a finite number of Hz above 0. ValueError otherwise."""
    number = _number(value)
    if number is None or number <= 0:
        raise ValueError(f"a logger's bandwidth is a number of Hz above 0, got {value!r}")
    return number


def _number(value: object) -> float | None:
    """``value`` as a finite float when it is a number (not text: a mapping's ``"0.4"`` in quotes is
    refused, as everywhere in a TOML file), else None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def from_text(text: str) -> float | str:
    """A value typed on the command line: the number it spells, else the text itself."""
    try:
        return float(text)
    except ValueError:
        return text


def merged(recorded: MeasurementChain, given: MeasurementChain) -> MeasurementChain:
    """The chain the measurement records (its mapping) with what the command line gives; both may
    state a value only when they agree (as a tyre pressure given and recorded must). ValueError
    naming both otherwise."""
    values = {}
    for name in ("hub_lag_ms", "bandwidth_hz"):
        a, b = getattr(recorded, name), getattr(given, name)
        if a is not None and b is not None and not _same(a.value, b.value):
            raise ValueError(f"{b.where} {b.value!r} contradicts the {a.value!r} that {a.where} states")
        values[name] = b or a
    return MeasurementChain(**values)


def _same(a: float | str, b: float | str) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return abs(a - b) <= 1e-9 * max(abs(a), abs(b), 1.0)
