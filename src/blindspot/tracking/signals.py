"""SIGTERM as an exception: a killed stage ends its MLflow run KILLED and exits 143.

:func:`sigterm_as_exit` turns SIGTERM into :class:`Terminated` (a ``SystemExit``), so ``finally``
blocks run (the run is closed, :mod:`blindspot.io` removes half-written temporary files);
:func:`sigterm_deferred` holds a SIGTERM back while a run-state write must not be cut.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["Terminated", "sigterm_as_exit", "sigterm_deferred"]

_SIGTERM_EXIT = 128 + signal.SIGTERM  # 143


class Terminated(SystemExit):
    """Raised inside the process by the SIGTERM handler; exits with status 143."""

    def __init__(self) -> None:
        super().__init__(_SIGTERM_EXIT)


@contextlib.contextmanager
def sigterm_as_exit() -> Iterator[None]:
    """Turn SIGTERM into :class:`Terminated` (SystemExit 143) while the body runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def sigterm_deferred() -> Iterator[None]:
    """Hold a SIGTERM back while the body runs (a run-state write), then deliver it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
        if received:
            if callable(previous):
                previous(signal.SIGTERM, None)
            elif previous != signal.SIG_IGN:
                raise Terminated()
