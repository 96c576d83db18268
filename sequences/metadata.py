"""The test's metadata: what was tested (the sensor, the tyre), on which bench, by whom, and notes.

Eight named texts, each empty when not given. They are given in the bench configuration's and the
sequence file's ``[metadata]`` table and on the command line (``--meta KEY=VALUE``), a later
source winning over an earlier one for each key it gives (:func:`merged`), and recorded with the
campaign (docs/hdf5.md, *Test metadata*). This module is the one definition of their names, of
what a valid value is (text; the calibration date an ISO date ``YYYY-MM-DD``) and of what a run
that states other values than its campaign's may do (:func:`specimen_conflicts`).
"""

from __future__ import annotations

import datetime
import re
from collections.abc import Mapping

#: The names, in the order they are shown. Campaign files keep them as attributes of ``/`` under
#: these names (``bench.store.schema.METADATA_FIELDS`` is this tuple).
METADATA_FIELDS = (
    "bench_id",
    "sensor_serial",
    "sensor_calibration_date",
    "tyre_make",
    "tyre_size",
    "tyre_id",
    "operator",
    "notes",
)
#: What each run records as its own too: who ran it, on which bench, and what they noted. A later
#: session (a resume, another sequence into the file) may state other values: they are its runs'.
RUN_FIELDS = ("bench_id", "operator", "notes")
#: What the campaign tested: one campaign file holds one sensor and one tyre, so a later session
#: that states other values is refused (:func:`specimen_conflicts`).
SPECIMEN_FIELDS = tuple(name for name in METADATA_FIELDS if name not in RUN_FIELDS)
#: Fields whose value is a date, written ``YYYY-MM-DD``.
DATE_FIELDS = ("sensor_calibration_date",)
#: How reports and the terminal UI name each field.
LABELS = {
    "bench_id": "bench",
    "sensor_serial": "sensor serial number",
    "sensor_calibration_date": "sensor calibrated on",
    "tyre_make": "tyre make",
    "tyre_size": "tyre size",
    "tyre_id": "tyre identifier",
    "operator": "operator",
    "notes": "notes",
}

_ISO_DATE = re.compile(r"[0-9]{4}-[0-9]{2}-[0-9]{2}")


def metadata_value(name: str, value: object) -> str:
    """``value`` as the text recorded for the field ``name``; ValueError saying why it is refused:
    an unknown name, a value that is not text, a date that is not ``YYYY-MM-DD`` (a TOML date such
    as ``2026-03-01`` without quotes is taken as that date; a date with a time is refused)."""
    if name not in METADATA_FIELDS:
        raise ValueError(f"unknown key; allowed: {', '.join(METADATA_FIELDS)}")
    if name in DATE_FIELDS and type(value) is datetime.date:
        return value.isoformat()
    if not isinstance(value, str):
        kind = "a date and time" if isinstance(value, datetime.datetime) else type(value).__name__
        raise ValueError(f"expected text (a string in quotes), got {value!r} ({kind})")
    if name in DATE_FIELDS and value:
        if _ISO_DATE.fullmatch(value) is None:
            raise ValueError(f"{value!r} is not a date written YYYY-MM-DD (e.g. 2026-03-01)")
        try:
            datetime.date.fromisoformat(value)
        except ValueError:
            raise ValueError(f"{value!r} is no date of the calendar (month 1-12, its days)") from None
    return value


def check_metadata(table: object, key: str = "metadata") -> tuple[dict[str, str], list[tuple[str, str]]]:
    """The fields a ``[metadata]`` table gives, and its problems as (key, reason) pairs, each key
    named as in the file (``metadata.tyre_id``); every problem of the table is found."""
    if not isinstance(table, Mapping):
        return {}, [(key, f"must be a table of texts, got {table!r}")]
    given: dict[str, str] = {}
    problems: list[tuple[str, str]] = []
    for name, value in table.items():
        try:
            given[name] = metadata_value(name, value)
        except ValueError as exc:
            problems.append((f"{key}.{name}", str(exc)))
    return given, problems


def parse_assignment(text: str) -> tuple[str, str]:
    """A command line's ``KEY=VALUE`` as (key, value); ValueError naming it and why when refused
    (no ``=``, an unknown key, a date that is not ``YYYY-MM-DD``). ``KEY=`` gives an empty value,
    which clears what a file gave."""
    name, equals, value = text.partition("=")
    name = name.strip()
    if not equals:
        raise ValueError(f"{text!r}: expected KEY=VALUE, one of {', '.join(METADATA_FIELDS)}")
    try:
        return name, metadata_value(name, value)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None


def merged(*layers: Mapping[str, str]) -> dict[str, str]:
    """Every field, from the layers in order: a layer's value for a key it gives replaces the
    earlier ones' (an empty value too); a key no layer gives is empty."""
    out = dict.fromkeys(METADATA_FIELDS, "")
    for layer in layers:
        out.update({name: layer[name] for name in METADATA_FIELDS if name in layer})
    return out


def specimen_conflicts(campaign: Mapping[str, str], stated: Mapping[str, str]) -> list[tuple[str, str, str]]:
    """The specimen fields (:data:`SPECIMEN_FIELDS`) a session states otherwise than the campaign
    recorded them, as (field, stated, recorded): both given and different. A field the campaign
    left empty, or the session does not state, is no conflict."""
    return [
        (name, stated[name], campaign[name])
        for name in SPECIMEN_FIELDS
        if stated.get(name) and campaign.get(name) and stated[name] != campaign[name]
    ]
