"""Keys typed into the UI under test as a terminal delivers them: in order, without waiting for the
app to look idle in between.

Textual's ``Pilot.press`` waits, after each key, until the process's CPU time stops advancing (up to
1 s, twice). With the simulated bench in the test's own process that never happens while a run
goes, so each key cost 2 s of wall-clock time and a test's run outlasted what it was about. Here a
key is handed to the app's driver, as the terminal driver hands it over, and the call returns once
the app and every widget of its screen have taken the messages queued until then (a barrier, taken
once per hop a key makes: app, screen, focused widget). What a key then starts (a dialog opening, a
sequence starting) is awaited by the tests' ``until``, on the condition itself.
"""

from __future__ import annotations

import asyncio

from textual import events
from textual.app import App

#: The character each named key types (a terminal sends it with the key's name)
_CHARACTERS = {"question_mark": "?", "enter": "\r", "tab": "\t", "escape": "\x1b", "space": " "}
#: Message hops a key makes before it is handled: the app, the screen, the focused widget
_HOPS = 3
#: Bound of the wait for the app to take a key (s): an app that stopped handling messages fails the
#: test instead of hanging it; the wait ends on the barrier, not on time
_TAKEN_TIMEOUT_S = 60.0


async def taken(app: App) -> None:
    """Return once the app and every widget of its screen have handled what was queued to them."""
    nodes = [app, *app.screen.walk_children(with_self=True)]
    done = [asyncio.Event() for _ in nodes]
    for node, event in zip(nodes, done, strict=True):
        if not node.call_later(event.set):
            event.set()  # a node that closed takes nothing more
    try:
        await asyncio.wait_for(asyncio.gather(*(event.wait() for event in done)), _TAKEN_TIMEOUT_S)
    except TimeoutError:
        raise AssertionError(f"the app took no key for {_TAKEN_TIMEOUT_S} s") from None


async def press(pilot, *keys: str) -> None:
    """Type ``keys`` (textual's key names: "f3", "enter", "a") into the app, one after another."""
    app = pilot.app
    for key in keys:
        app._driver.send_message(events.Key(key, key if len(key) == 1 else _CHARACTERS.get(key)))
        for _ in range(_HOPS):
            await taken(app)
