"""The simulated acquisition's triggered capture: arm, find the trigger, cut the block.

Device side of ``CAPTURE`` (the message is in ``drivers/wfs_capture.py``). The acquisition keeps
the latest converter samples of Fz; arming takes its baseline from the last
:data:`BASELINE_SAMPLES` of them and the pre-trigger samples from the same history, so a blow that
comes right after the ``$OK`` reply is caught with its full pre-trigger. Only samples converted
after arming can fire the trigger.
"""

from __future__ import annotations

import numpy as np

from drivers.wfs_capture import MAX_CAPTURE_SAMPLES, Capture

#: the baseline is the mean Fz over this many converter samples before arming (10 ms at 10 kHz)
BASELINE_SAMPLES = 100
#: converter samples the acquisition keeps for baseline and pre-trigger (1 s at 10 kHz)
HISTORY_SAMPLES = 10_000


class CaptureTrigger:
    """One armed capture: feed it converter samples until it returns the finished :class:`Capture`."""

    def __init__(
        self,
        history_n: np.ndarray,
        *,
        rate_hz: float,
        trigger_level_n: float,
        pre_trigger_samples: int,
        length_samples: int,
    ) -> None:
        if not 0 < length_samples <= MAX_CAPTURE_SAMPLES or not 0 <= pre_trigger_samples < length_samples:
            raise ValueError(f"capture of {length_samples} samples, {pre_trigger_samples} before the trigger")
        if not trigger_level_n > 0:
            raise ValueError(f"trigger level {trigger_level_n} N must be positive")
        self.rate_hz = rate_hz
        self.level_n = trigger_level_n
        self.pre = pre_trigger_samples
        self.length = length_samples
        keep = max(self.pre, BASELINE_SAMPLES)
        self._buffer = np.asarray(history_n, dtype=float)[-keep:]
        self._search_from = len(self._buffer)  # only samples after arming fire the trigger
        self.baseline_n: float | None = None
        if len(self._buffer) >= BASELINE_SAMPLES:
            self.baseline_n = float(np.mean(self._buffer[-BASELINE_SAMPLES:]))
        self._trigger_at: int | None = None

    def feed(self, fz_n: np.ndarray) -> Capture | None:
        """Add converter samples; return the capture once its last sample has arrived."""
        self._buffer = np.concatenate([self._buffer, fz_n])
        if self.baseline_n is None:
            if len(self._buffer) < BASELINE_SAMPLES:
                return None
            self.baseline_n = float(np.mean(self._buffer[:BASELINE_SAMPLES]))
            self._search_from = BASELINE_SAMPLES
        if self._trigger_at is None:
            beyond = np.abs(self._buffer[self._search_from :] - self.baseline_n) > self.level_n
            if not beyond.any():
                drop = max(0, len(self._buffer) - max(self.pre, BASELINE_SAMPLES))
                self._buffer = self._buffer[drop:]
                self._search_from = len(self._buffer)
                return None
            self._trigger_at = self._search_from + int(np.argmax(beyond))
        start = max(0, self._trigger_at - self.pre)
        if len(self._buffer) < start + self.length:
            return None
        samples = self._buffer[start : start + self.length].copy()
        return Capture(samples, self.rate_hz, self._trigger_at - start, self.level_n, self.baseline_n)
