"""How a run is named in the campaign file: the sequence's name, the step's position and its kind.

The engine names each measurement step's run with :func:`run_id` (``Engine.run_id``), so that runs
of several sequences share a campaign file and a resume finds its runs again; :data:`RUN_ID` reads
the parts back (``wfsbench analyze`` lists the sequences a file holds by it). Both live here, apart
from the engine, so that the offline commands can read run ids without loading the engine.
"""

from __future__ import annotations

import re

from sequences import Sequence

#: A run id as :func:`run_id` writes it: ``<sequence>-s<step index>-<step kind>``.
RUN_ID = re.compile(r"^(?P<sequence>.+)-s(?P<step>[0-9]{3,})-(?P<kind>[a-z_]+)$")


def run_id(sequence: Sequence, index: int) -> str:
    """The run id of the measurement step ``sequence.steps[index]`` (:data:`RUN_ID` reads it back)."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", sequence.name) or "sequence"
    return f"{name}-s{index:03d}-{sequence.steps[index].kind}"
