"""What an analysis flags, typed: each flag a :class:`FlagCode` and its text.

A flag is something a reader must not miss: a result not to be trusted, a point left out, a limit
the run reached. The analysis's text says it on a line of its own, ``FLAG <text>``
(:class:`FlagLine`, made by :func:`flag`: the one way a flag is made); the run's analysis keeps the
flags beside its lines (:attr:`bench.analysis.campaign.RunAnalysis.flags`), so that the JSON, the
report and the index list them by code without reading the text.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum


class FlagCode(StrEnum):
    """What kind of thing a flag says (the ``code`` of the JSON's and the index's flags)."""

    ANALYSIS_FAILED = "analysis_failed"  # the run's analysis raised: its reason
    LIMIT_REACHED = "limit_reached"  # the run reached a limit (an amplitude excursion, a response alarm)
    NOT_SETTLED = "not_settled"  # a dwell left out: not settled in its window
    REJECTED = "rejected"  # a dwell left out: its signal not usable
    REPEATS_DIFFER = "repeats_differ"  # repeats of a point differ far outside their noise
    DAMPING_DISAGREES = "damping_disagrees"  # the hammer's two damping estimates disagree
    NOMINAL_M_COMP = "nominal_m_comp"  # m_comp not measured: a nominal value taken
    FREE_RUN = "free_run"  # a finding of the free run's m_comp (its misfit, a wheel left on)
    FIT_NOT_CONVERGED = "fit_not_converged"  # a model's or the quarter car's fit did not converge
    IDENTIFICATION = "identification"  # a finding of a tyre or quarter-car identification
    UNRELIABLE_BINS = "unreliable_bins"  # sweep bins whose FRF is not to be trusted
    NO_TYRE_AT_PRESSURE = "no_tyre_at_pressure"  # no shaker identification at the car's pressure
    TRACK_STOPPED = "track_stopped"  # a tracked dwell stopped before its end
    NOT_CONVERGED = "not_converged"  # a drive iteration ended at its largest count, its stop rules unmet


@dataclass(frozen=True)
class Flag:
    """One flag: its ``code`` and its ``text`` (the line without its ``FLAG`` word)."""

    code: FlagCode
    text: str

    @property
    def line(self) -> str:
        """The flag as the analysis's text prints it."""
        return f"FLAG {self.text}"


class FlagLine(str):
    """A line of the analysis's text that is a flag: reads as the line, carries its :class:`Flag`."""

    flag: Flag

    def __new__(cls, flag: Flag) -> FlagLine:
        line = super().__new__(cls, flag.line)
        line.flag = flag
        return line

    def __reduce__(self) -> tuple[type[FlagLine], tuple[Flag]]:
        """Made again from its flag: the post-run analysis sends its lines from its own process."""
        return FlagLine, (self.flag,)


def flag(code: FlagCode, text: str) -> FlagLine:
    """The line ``FLAG <text>`` carrying its code."""
    return FlagLine(Flag(code, text))


def flags_of(lines: Iterable[str]) -> tuple[Flag, ...]:
    """The flags among ``lines``, in order."""
    return tuple(line.flag for line in lines if isinstance(line, FlagLine))
