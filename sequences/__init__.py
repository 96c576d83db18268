"""Test sequences: the step vocabulary, the sequence-file loader and validator, standard files.

Build a sequence in Python from the steps and check it with :func:`validate`, or load a file with
:func:`load_sequence`; both report problems the same way (:class:`SequenceError`).
"""

from importlib import resources
from pathlib import Path

from sequences.errors import AnswerError, Problem, SequenceError
from sequences.limits import BenchLimits, peak_acceleration_m_s2, peak_velocity_mm_s
from sequences.loader import dump_sequence, load_sequence, parse_sequence
from sequences.steps import (
    AdaptiveDwell,
    DriveIteration,
    DwellGrid,
    FreeRun,
    HammerTest,
    Hydraulics,
    MeanPosition,
    Prompt,
    RoadReplay,
    Sequence,
    SineDwell,
    Step,
    Sweep,
    Tare,
    TrackedDwell,
    crossover_amplitude_mm,
    step_fields,
)
from sequences.validation import validate


def shipped_file(name: str) -> Path:
    """A sequence file shipped with the package, e.g. ``shipped_file("smoke.toml")``."""
    return Path(str(resources.files("sequences") / "files" / name))


def shipped_files() -> tuple[str, ...]:
    """The names of the sequence files shipped with the package, sorted."""
    return tuple(
        sorted(
            p.name
            for p in resources.files("sequences").joinpath("files").iterdir()
            if p.name.endswith(".toml")
        )
    )


__all__ = [
    "AdaptiveDwell",
    "AnswerError",
    "BenchLimits",
    "DriveIteration",
    "DwellGrid",
    "FreeRun",
    "HammerTest",
    "Hydraulics",
    "MeanPosition",
    "Problem",
    "Prompt",
    "RoadReplay",
    "Sequence",
    "SequenceError",
    "SineDwell",
    "Step",
    "Sweep",
    "Tare",
    "TrackedDwell",
    "crossover_amplitude_mm",
    "dump_sequence",
    "load_sequence",
    "parse_sequence",
    "peak_acceleration_m_s2",
    "peak_velocity_mm_s",
    "shipped_file",
    "shipped_files",
    "step_fields",
    "validate",
]
