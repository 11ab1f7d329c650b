"""One batch (sweep, scan) at a time on an output: an exclusive lock on ``<output>.lock``
held while the batch runs (``flock``: the system releases it however the process ends, ``kill -9``
included, so a stale lock file never blocks a later batch)."""

from __future__ import annotations

import os
import socket
import time
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no flock, no lock
    fcntl = None


def lock_path(output: Path) -> Path:
    """The lock file of a batch writing ``output``: ``<output>.lock``."""
    return Path(output).with_name(Path(output).name + ".lock")


@contextmanager
def output_lock(output: Path, what: str = "sweep"):
    """Hold an exclusive lock on ``output`` for the duration of a batch (``what``: its
    name in the message): ``<output>.lock``, ``flock``-ed (released by the system however
    the process ends, ``kill -9`` included) and holding who holds it.  A second batch on the
    same output raises InputError naming the first (pid, host, start time).  The lock file
    is removed on exit."""
    if fcntl is None:  # pragma: no cover - no flock (Windows): no lock
        yield
        return
    path = lock_path(output)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.read(fd, 500).decode(errors="replace").strip() or "unknown process"
            os.close(fd)
            raise InputError(
                f"{output} is being written by another {what} ({holder}); wait for it to end or choose another -o"
            ) from None
        # the previous holder may have removed the file between our open and our lock: lock the file at the path
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    started = time.strftime("%Y-%m-%d %H:%M:%S")
    os.ftruncate(fd, 0)
    os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}, started {started}".encode())
    try:
        yield
    finally:
        path.unlink(missing_ok=True)
        os.close(fd)
