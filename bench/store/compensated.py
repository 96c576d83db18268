"""The output of ``wfsbench compensate``: the compensated contact force of a measurement with its
95 % band, as one HDF5 file (layout in docs/compensate.md).

The samples are written block by block as the compensation produces them, into a temporary file
beside the output that is linked into place once complete: a refused or failed compensation leaves
no file, and an existing file is never replaced.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from bench.analysis.measurement_compensation import CompensatedBlock
from bench.store.schema import GZIP_LEVEL, LIBVER
from bench.store.temporary import temporary_beside

SCHEMA_NAME = "wfs-bench compensated force"
SCHEMA_VERSION = 1
#: Samples per chunk of the per-sample datasets.
CHUNK_SAMPLES = 16384
#: The per-sample datasets: name -> (dtype, unit, description).
SERIES = {
    "t_s": ("f8", "s", "time of the sample in the measurement's own time (its time column or stamps)"),
    "f_contact_n": ("f4", "N", "compensated contact force, positive in compression; NaN where not computed"),
    "u95_n": (
        "f4",
        "N",
        "95 % half-width of the contact force: the true force lies in f_contact_n +/- u95_n",
    ),
}


class OutputExistsError(FileExistsError):
    """The output file exists: it is never replaced."""


def write_compensated(
    path: str | Path,
    *,
    n_samples: int,
    sample_rate_hz: float,
    start_s: float = 0.0,
    blocks: Iterable[CompensatedBlock],
    attributes: Mapping[str, Any],
    arrays: Mapping[str, np.ndarray],
    replace: bool = False,
) -> Path:
    """Write the ``blocks`` of a compensated record of ``n_samples`` at ``sample_rate_hz``, its first
    at ``start_s`` in the measurement's time, to a new
    file at ``path`` with the root ``attributes`` (numbers, strings, pairs of numbers) and the
    ``arrays`` (``group/name`` -> array: the filters, the parameters and their covariance).
    ``replace``: an older output at ``path`` is replaced (a job's own output of an input that
    changed); else an existing file is refused."""
    path = Path(path)
    if path.exists() and not replace:
        raise OutputExistsError(f"{path}: exists; the output is never replaced (choose another --out)")
    temporary = temporary_beside(path)
    try:
        with h5py.File(temporary, "w", libver=LIBVER) as f:
            f.attrs["schema"] = SCHEMA_NAME
            f.attrs["schema_version"] = SCHEMA_VERSION
            for key, value in attributes.items():
                f.attrs[key] = value
            for key, value in arrays.items():
                f.create_dataset(key, data=value)
            datasets = {}
            for name, (dtype, unit, description) in SERIES.items():
                ds = f.create_dataset(
                    name,
                    shape=(n_samples,),
                    dtype=dtype,
                    chunks=(min(CHUNK_SAMPLES, max(n_samples, 1)),),
                    compression="gzip",
                    compression_opts=GZIP_LEVEL,
                    shuffle=True,
                )
                ds.attrs["unit"], ds.attrs["description"] = unit, description
                datasets[name] = ds
            written = 0
            for block in blocks:
                stop = block.start + block.force_n.size
                datasets["t_s"][block.start : stop] = start_s + np.arange(block.start, stop) / sample_rate_hz
                datasets["f_contact_n"][block.start : stop] = block.force_n
                datasets["u95_n"][block.start : stop] = block.u95_n
                written = stop
            if written != n_samples:
                raise RuntimeError(f"{written} of {n_samples} samples compensated")
        if replace:
            os.replace(temporary, path)
        else:
            try:
                os.link(temporary, path)  # never over a file that appeared meanwhile
            except FileExistsError:
                raise OutputExistsError(
                    f"{path}: exists; the output is never replaced (choose another --out)"
                ) from None
    finally:
        temporary.unlink(missing_ok=True)
    return path
