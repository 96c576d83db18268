"""Starting one of the bench's own modules as a child process (the simulated lab, the analysis).

The child is this interpreter running ``python -m <module>``, with the directory that holds the
``bench`` package first on its import path (a bench started from a script or another directory
finds its own code in the child too), its standard input and output piped to the parent, its
standard error discarded (nothing of it may reach a terminal UI: the child reports on its standard
output), and in a session of its own, so that Ctrl-C at the terminal reaches the bench, which then
ends the child in order. A child ends when its standard input closes, which happens too when the
bench process dies, however it dies.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

#: The directory that holds the ``bench`` package.
CODE_ROOT = Path(__file__).resolve().parents[2]


def start_child(module: str, *, text: bool) -> subprocess.Popen:
    """``python -m module`` as a child (see the module's docstring); ``text``: line-buffered text
    pipes, else binary ones."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(CODE_ROOT), env.get("PYTHONPATH", "")) if p)
    return subprocess.Popen(
        [sys.executable, "-m", module],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=text,
        bufsize=1 if text else -1,
        start_new_session=True,
        env=env,
    )
