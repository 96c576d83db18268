"""The web monitor: a read-only page and JSON state of a running bench or a campaign file.

``listen`` (where it listens, who may read it), ``view`` (the bench's state made from the engine's
events), ``feed`` (the engine's bus into the view through a bounded queue, on a thread of its own),
``file_view`` (the same state read from a campaign file), ``server`` (the HTTP server: the page,
``/api/state`` and the stream of updates, on a thread and event loop of its own). docs/monitor.md.
"""
