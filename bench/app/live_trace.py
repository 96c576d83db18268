"""The last seconds of the live channels, shared by the front ends that show a run as it goes
(the terminal UI's plots and values, the web monitor's values).

Written by one thread (the engine's, or a front end's feeder), read by another at its own rate: a
front end never holds up the engine to draw.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from sequences.channels import ChannelSet, Role, standard_name

#: The roles shown live (wheel-frame Fz, plate force, displacement, hub acceleration), each under its
#: standard name whatever the bench calls its channel.
LIVE_ROLES = (Role.WFS_FZ, Role.PLATE_FORCE, Role.BENCH_DISPLACEMENT, Role.HUB_ACCELERATION)


class LiveTrace:
    """The last ``window_s`` seconds of the live channels, written by the engine's thread and read
    by the UI's; the UI decimates what it draws."""

    def __init__(self, sample_rate_hz: float, channels: ChannelSet, window_s: float = 5.0) -> None:
        """``channels``: the bench's recorded channels; the live roles are read from theirs."""
        self.sample_rate_hz = sample_rate_hz
        self._n = max(1, int(sample_rate_hz * window_s))
        self._lock = threading.Lock()
        self._sources = {
            standard_name(role): channels.name_of(role) for role in LIVE_ROLES if channels.bound(role)
        }
        self._data = {standard_name(role): np.zeros(self._n, dtype=np.float64) for role in LIVE_ROLES}
        self._filled = 0
        self.samples_seen = 0
        self.last_seen_s: float | None = None  # time.monotonic() of the newest samples
        self.last_run: str | None = None  # the run that recorded them

    def append(self, columns: dict[str, np.ndarray], run_id: str | None = None) -> None:
        present = [name for name, source in self._sources.items() if source in columns]
        if not present:
            return
        self.last_seen_s, self.last_run = time.monotonic(), run_id
        n = len(columns[self._sources[present[0]]])
        with self._lock:
            for name in present:
                block = np.asarray(columns[self._sources[name]], dtype=np.float64)[-self._n :]
                buf = self._data[name]
                buf[: self._n - len(block)] = buf[len(block) :]
                buf[self._n - len(block) :] = block
            self._filled = min(self._n, self._filled + n)
            self.samples_seen += n

    def snapshot(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(time in s relative to the newest sample, values by channel) of what has been seen."""
        with self._lock:
            k = self._filled
            values = {name: buf[self._n - k :].copy() for name, buf in self._data.items()}
        t_s = (np.arange(k) - (k - 1)) / self.sample_rate_hz
        return t_s, values

    def latest(self) -> dict[str, float]:
        with self._lock:
            if not self._filled:
                return {}
            return {name: float(buf[-1]) for name, buf in self._data.items()}

    def age_s(self) -> float | None:
        """Seconds since the newest samples arrived (None: none yet)."""
        return None if self.last_seen_s is None else time.monotonic() - self.last_seen_s
