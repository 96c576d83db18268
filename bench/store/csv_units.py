"""Units of a CSV import (docs/import.md): the units a column may be given in, how other
acquisition systems spell them, and the SI unit a channel's name promises.

Exports spell units as their software likes: ``m/s²`` with a superscript, ``µm`` with the micro
sign or the Greek mu, ``N·m`` with a middle dot, ``°`` for degrees. :func:`unit_named` folds every
such spelling onto one key of :data:`UNITS`, so each unit is defined once.
"""

from __future__ import annotations

import math
import re
import unicodedata

#: Units a column may be given in: unit -> (the SI unit of the schema's channel, factor to it).
UNITS: dict[str, tuple[str, float]] = {
    "N": ("N", 1.0),
    "kN": ("N", 1e3),
    "Nm": ("N m", 1.0),
    "kNm": ("N m", 1e3),
    "m": ("m", 1.0),
    "mm": ("m", 1e-3),
    "µm": ("m", 1e-6),
    "m/s^2": ("m/s^2", 1.0),
    "g": ("m/s^2", 9.80665),
    "rad": ("rad", 1.0),
    "deg": ("rad", math.pi / 180),
    "s": ("s", 1.0),
    "ms": ("s", 1e-3),
    "µs": ("s", 1e-6),
}
#: The SI unit a channel's name promises by its suffix (docs/hdf5.md: units in names).
CHANNEL_SUFFIX_UNITS = (("_m_s2", "m/s^2"), ("_nm", "N m"), ("_n", "N"), ("_m", "m"), ("_rad", "rad"))
#: The unit of the CSV's time column once converted: seconds.
TIME_UNIT = "s"
#: What exports write between a unit's symbols (N·m, N m, m/s^2): nothing for the unit.
_JOINERS = re.compile(r"[\s·⋅*^]")


def _folded(spelling: str) -> str:
    """``spelling`` reduced to plain symbols: NFKC folds ``²`` into ``2`` and the micro sign into
    the Greek mu, which is written ``u``; ``°`` is ``deg``; joiners between symbols are dropped."""
    text = unicodedata.normalize("NFKC", spelling).strip().replace("μ", "u").replace("°", "deg")
    return _JOINERS.sub("", text)


_BY_FOLDED = {_folded(unit): unit for unit in UNITS}


def unit_named(spelling: str) -> str | None:
    """The key of :data:`UNITS` that ``spelling`` stands for (``m/s²``, ``m/s2``, ``m/s^2``:
    ``m/s^2``; ``µm``, ``μm``, ``um``: ``µm``; ``°``: ``deg``), None when it names no known unit."""
    return _BY_FOLDED.get(_folded(spelling))


def known_units() -> str:
    """The known units for an error message."""
    return ", ".join(UNITS)


def channel_si_unit(name: str) -> str | None:
    """The SI unit promised by a channel name's suffix (``fz_wfs_n``: N), None when there is none."""
    for suffix, unit in CHANNEL_SUFFIX_UNITS:
        if name.endswith(suffix):
            return unit
    return None
