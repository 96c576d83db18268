"""The errors of sequences: a problem names the file, the key and the reason; an error holds them all.

A sequence file is checked as a whole before anything moves, so one error carries every problem
found in the file (``SequenceError.problems``), in file order; its first line is the first problem.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Problem:
    """One thing wrong with a sequence: where (``source`` file, ``key`` such as ``steps[3].amplitude_mm``)
    and why (``message``, with the allowed range where there is one)."""

    source: str
    key: str
    message: str

    def __str__(self) -> str:
        return f"{self.source}: {self.key}: {self.message}" if self.key else f"{self.source}: {self.message}"


def problems_text(problems: Iterable[object]) -> str:
    """Several problems as one error message: the first on the first line, the others indented
    below it after how many there are."""
    lines = [str(p) for p in problems]
    if len(lines) > 1:
        lines[1:] = [f"  and {len(lines) - 1} more:", *(f"  {line}" for line in lines[1:])]
    return "\n".join(lines)


class SequenceError(ValueError):
    """A sequence is refused; ``problems`` lists every problem found, the first one is in the str."""

    def __init__(self, source: str, key: str, message: str, more: Iterable[Problem] = ()) -> None:
        self.problems: tuple[Problem, ...] = (Problem(source, key, message), *more)
        self.source, self.key, self.message = source, key, message
        super().__init__(problems_text(self.problems))

    @classmethod
    def of(cls, problems: Iterable[Problem]) -> SequenceError:
        """One error for several problems (at least one)."""
        first, *rest = problems
        return cls(first.source, first.key, first.message, rest)


class AnswerError(ValueError):
    """An operator's answer to a prompt is refused; the message gives the allowed answers."""
