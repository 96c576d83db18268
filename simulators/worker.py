"""One background thread per simulated device: started once, stopped by an event it watches."""

from __future__ import annotations

import threading
from collections.abc import Callable


class Worker:
    """A daemon thread running ``target`` until :meth:`stop`; ``target`` polls :attr:`stopping`."""

    def __init__(self, target: Callable[[], None], name: str) -> None:
        self._target, self._name = target, name
        self.stopping = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._target, name=self._name, daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        self.stopping.set()
        if self._thread is not None:
            self._thread.join(timeout=timeout_s)
            self._thread = None
