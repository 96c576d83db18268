"""The output of ``wfsbench compensate``: the compensated contact force of a measurement with its
95 % band, as one HDF5 file (layout in docs/compensate.md).

The samples are written block by block as the compensation produces them, into a temporary file
beside the output that is linked into place once complete: a refused or failed compensation leaves
no file, and an existing file is never replaced.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
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


#: Samples read at a time from a compensated file's datasets (bounded memory on an hours-long record).
READ_BLOCK_SAMPLES = 16 * CHUNK_SAMPLES


class CompensatedFileError(ValueError):
    """A file that is no readable compensated force: the message names it and what is wrong."""


def is_compensated(path: Path) -> bool:
    """Whether ``path`` is a regular file that says it is a compensated force (its ``/@schema``); a
    FIFO or a device is never opened (it could block the reader)."""
    if not path.is_file():
        return False
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("schema") == SCHEMA_NAME
    except OSError:
        return False


def _plain(value: Any) -> Any:
    """An HDF5 attribute as a plain Python value: text, number or list of numbers."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return value.item()
    return value


class CompensatedFile:
    """A compensated force file opened to be read (:func:`open_compensated`): its root
    ``attributes`` as plain values, its ``n_samples`` and ``sample_rate_hz``, and its per-sample
    datasets (:data:`SERIES`) read block by block."""

    def __init__(self, path: Path, file: h5py.File) -> None:
        self.path = path
        self._file = file
        self.attributes: dict[str, Any] = {key: _plain(value) for key, value in file.attrs.items()}
        try:
            self.n_samples = int(file["f_contact_n"].shape[0])
            self.sample_rate_hz = float(self.attributes["sample_rate_hz"])
            for name in SERIES:
                if file[name].shape != (self.n_samples,):
                    count, n = file[name].shape[0], self.n_samples
                    raise CompensatedFileError(f"{path}: /{name} has {count} samples, /f_contact_n {n}")
        except (KeyError, OSError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise CompensatedFileError(f"{path}: damaged: {exc}") from None

    def unit(self, name: str) -> str:
        return SERIES[name][1]

    def blocks(self) -> Iterator[dict[str, np.ndarray]]:
        """The per-sample datasets, :data:`SERIES` in order, :data:`READ_BLOCK_SAMPLES` at a time."""
        size = READ_BLOCK_SAMPLES
        for start in range(0, self.n_samples, size):
            stop = min(start + size, self.n_samples)
            try:
                block = {name: self._file[name][start:stop] for name in SERIES}
            except (OSError, RuntimeError, ValueError) as exc:  # a damaged chunk
                raise CompensatedFileError(f"{self.path}: damaged at samples {start}-{stop}: {exc}") from None
            yield block


@contextmanager
def open_compensated(path: str | Path) -> Iterator[CompensatedFile]:
    """The compensated force file at ``path``, read-only; :class:`CompensatedFileError` naming the
    file when it is none (not HDF5, another schema, a newer version, damaged)."""
    path = Path(path)
    if not path.is_file():
        what = "no such file" if not path.exists() else "not a regular file"
        raise CompensatedFileError(f"{path}: {what}")
    try:
        file = h5py.File(path, "r")
    except OSError as exc:
        raise CompensatedFileError(f"{path}: not a readable HDF5 file: {exc}") from None
    with file:
        schema, version = _plain(file.attrs.get("schema")), _plain(file.attrs.get("schema_version"))
        if schema != SCHEMA_NAME:
            raise CompensatedFileError(f"{path}: not a compensated force (schema {schema!r})")
        if version != SCHEMA_VERSION:
            raise CompensatedFileError(
                f"{path}: compensated force schema version {version!r}: this version reads {SCHEMA_VERSION}"
            )
        yield CompensatedFile(path, file)
