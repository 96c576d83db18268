"""The compensated contact force of a measurement as an ASAM MDF 4 file (written by asammdf),
beside its HDF5 output, so that the lab's MDF tools open it (docs/compensate.md, *Many
measurements*).

One channel group: the master channel ``time`` (s, the measurement's own time), ``f_contact_n`` and
``u95_n`` (float32, NaN where not computed), as the HDF5 output's series. The samples are appended
block by block (asammdf keeps them in a temporary file until the file is saved), so the memory
does not grow with the record; the file is saved under a temporary name and moved into place.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from bench.export.mdf4 import MDF_VERSION
from bench.store.compensated import SERIES
from bench.store.temporary import temporary_beside


class CompensatedMdf4:
    """Writes the compensated series of one measurement to ``path``: :meth:`add` each block in
    order, then :meth:`save` (or :meth:`discard`). ``comment``: the file's header comment."""

    def __init__(self, path: Path, *, sample_rate_hz: float, start_s: float, comment: str) -> None:
        from asammdf import MDF  # a second or more to import: only when writing

        self.path, self.sample_rate_hz, self.start_s = path, sample_rate_hz, start_s
        self._mdf = MDF(version=MDF_VERSION)
        self._mdf.header.comment = comment
        self._appended = False

    def add(self, start: int, force_n: np.ndarray, u95_n: np.ndarray) -> None:
        """Samples ``start`` to ``start + len(force_n)``."""
        from asammdf import Signal

        t_s = self.start_s + np.arange(start, start + force_n.size) / self.sample_rate_hz
        columns = {"f_contact_n": force_n.astype(np.float32), "u95_n": u95_n.astype(np.float32)}
        if self._appended:
            self._mdf.extend(0, [(t_s, None), *((values, None) for values in columns.values())])
            return
        signals = [
            Signal(values, t_s, name=name, unit=SERIES[name][1], comment=SERIES[name][2])
            for name, values in columns.items()
        ]
        self._mdf.append(signals, comment="compensated contact force", common_timebase=True)
        self._appended = True

    def save(self, *, replace: bool = False) -> Path:
        """Save the file into place (over an older output when ``replace``)."""
        temporary = temporary_beside(self.path, suffix=".mf4")
        try:
            self._mdf.save(temporary, overwrite=True, compression=0)
            self._mdf.close()
            if replace:
                os.replace(temporary, self.path)
            else:
                os.link(temporary, self.path)
        finally:
            temporary.unlink(missing_ok=True)
        return self.path

    def discard(self) -> None:
        """Close without writing anything."""
        self._mdf.close()
