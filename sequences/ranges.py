"""The one wording of an out-of-range value, for sequence files and bench configurations alike.

A message says which bound the value crosses, what that bound is (``the 25 mm stroke``, or the
number itself) and the whole allowed range with its unit::

    0 mm is not above 0 (allowed 0 < amplitude_mm <= 25 mm)
    9 bar is above the prompt's maximum (allowed 0.5 <= target <= 4.5 bar)
    0.01 s is below the controller's shortest taper (allowed taper_in_s >= 0.1 s)

Whole numbers print as integers at any size (``4294967295``, not ``4.29497e+09``).
"""

from __future__ import annotations

import math


def fmt_number(value: float) -> str:
    """``value`` with up to 6 significant digits, a whole number in full."""
    if float(value).is_integer() and abs(value) < 1e16:
        return str(int(value))
    return f"{value:.6g}"


def allowed_range(
    name: str, lo: float | None, hi: float | None, *, lo_open: bool = False, unit: str = ""
) -> str:
    """``0 < name <= 25 mm``, ``name >= 0.1 s`` or ``name <= 4 bar`` (an infinite bound is no bound)."""
    lo = None if lo is None or math.isinf(lo) else lo
    hi = None if hi is None or math.isinf(hi) else hi
    u = f" {unit}" if unit else ""
    if lo is None and hi is None:
        return f"any finite {name}"
    if lo is None:
        return f"{name} <= {fmt_number(hi)}{u}"
    low = f"{'>' if lo_open else '>='} {fmt_number(lo)}"
    if hi is None:
        return f"{name} {low}{u}"
    return f"{fmt_number(lo)} {'<' if lo_open else '<='} {name} <= {fmt_number(hi)}{u}"


def range_problem(
    value: float,
    name: str,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    unit: str = "",
    lo_why: str = "",
    hi_why: str = "",
) -> str | None:
    """Why ``value`` is outside ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``), or None if it is inside.

    ``lo_why``/``hi_why`` name a bound (``the 25 mm stroke``) in place of its number."""
    if lo is not None and (value <= lo if lo_open else value < lo):
        side = f"{'not above' if lo_open else 'below'} {lo_why or fmt_number(lo)}"
    elif hi is not None and value > hi:
        side = f"above {hi_why or fmt_number(hi)}"
    else:
        return None
    u = f" {unit}" if unit else ""
    allowed = allowed_range(name, lo, hi, lo_open=lo_open, unit=unit)
    return f"{fmt_number(value)}{u} is {side} (allowed {allowed})"
