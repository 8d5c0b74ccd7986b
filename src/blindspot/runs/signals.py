"""Signals of a stage process: a killed stage ends its MLflow run KILLED, exits 143, and takes its
workers with it.

:func:`sigterm_as_exit` turns SIGTERM into :class:`Terminated` (a ``SystemExit``), so ``finally``
blocks run (the run is closed, :mod:`blindspot.io` removes half-written temporary files);
:func:`sigterm_deferred` holds a SIGTERM back while a run-state write must not be cut;
:func:`children_die_with_this_process` makes forked workers die with a SIGKILLed stage instead
of computing on, orphaned.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["Terminated", "sigterm_as_exit", "sigterm_deferred", "children_die_with_this_process"]

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


_PR_SET_PDEATHSIG = 1  # linux/prctl.h
_forker: list[int] = []  # the pid that is forking, read by the child
_hooked = False


def children_die_with_this_process() -> None:
    """From now on, every child this process forks (``os.fork``: a multiprocessing or
    ProcessPoolExecutor worker) gets SIGKILL when its parent dies.

    A SIGKILLed stage runs no ``finally``: without this its pool workers compute on, orphaned,
    then wait for work for ever. Linux only (``prctl(PR_SET_PDEATHSIG)``); a no-op elsewhere.
    Children started by ``subprocess`` (fork + exec) are not affected.
    """
    global _hooked
    if _hooked or not sys.platform.startswith("linux"):
        return
    os.register_at_fork(before=_remember_forker, after_in_child=_die_with_parent)
    _hooked = True


def _remember_forker() -> None:
    _forker[:] = [os.getpid()]


def _die_with_parent() -> None:
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):  # pragma: no cover - no prctl: nothing to do
        return
    if _forker and os.getppid() != _forker[0]:  # the parent died before prctl took effect
        os._exit(1)
