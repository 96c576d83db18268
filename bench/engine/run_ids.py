"""How a run is named in the campaign file: the sequence's name, the step's position and its kind.

The engine names each measurement step's run with :func:`run_id` (``Engine.run_id``), so that runs
of several sequences share a campaign file and a resume finds its runs again; :data:`RUN_ID` reads
the parts back (``wfsbench analyze`` lists the sequences a file holds by it). Both live here, apart
from the engine, so that the offline commands can read run ids without loading the engine.
"""

from __future__ import annotations

import re

from sequences import Sequence

#: A run id as :func:`run_id` writes it: ``<sequence>-s<step index>-<step kind>``, with
#: ``-i<iteration>`` after it for each run of a drive iteration (:func:`iteration_run_id`).
RUN_ID = re.compile(
    r"^(?P<sequence>.+)-s(?P<step>[0-9]{3,})-(?P<kind>[a-z_]+)(?:-i(?P<iteration>[0-9]{2,}))?$"
)


def run_id(sequence: Sequence, index: int) -> str:
    """The run id of the measurement step ``sequence.steps[index]`` (:data:`RUN_ID` reads it back)."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", sequence.name) or "sequence"
    return f"{name}-s{index:03d}-{sequence.steps[index].kind}"


def iteration_run_id(step_run_id: str, iteration: int) -> str:
    """The run id of iteration ``iteration`` (0: the rig's identification) of the drive iteration
    whose step's run id is ``step_run_id``."""
    return f"{step_run_id}-i{iteration:02d}"


def step_run_id(run_id: str) -> str:
    """The step's run id of ``run_id``: itself, or a drive iteration's run's step."""
    found = RUN_ID.match(run_id)
    if found is None or found["iteration"] is None:
        return run_id
    return run_id[: found.start("iteration") - 2]
