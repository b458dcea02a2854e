"""Stop signals, from a command's first instruction to its last file operation.

:func:`stop_signals` turns SIGTERM, SIGHUP, SIGQUIT and SIGUSR1 into ``KeyboardInterrupt`` (as
Ctrl-C already is), so a stop that arrives while a session is being opened, replayed or run
unwinds through the same clean path: the display zeroed, ``session_stopped`` logged when the
file is open, the file closed and checkpointed. :func:`signals_held` blocks every stop signal
(SIGINT included) while a file operation must run whole (opening, logging the stop, closing):
a signal that arrives then is delivered right after it. SIGKILL cannot be caught; the file
format makes it harmless (see :mod:`.recording`).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

from ..devices import STOP_SIGNALS

__all__ = ["signals_held", "stop_signals"]


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def stop_signals() -> Iterator[None]:
    """Inside, SIGTERM, SIGHUP, SIGQUIT and SIGUSR1 raise ``KeyboardInterrupt(<signal name>)``.

    The previous handlers are restored on exit. Outside the main thread (where Python cannot
    install handlers) it changes nothing.
    """
    if not _main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, _interrupt) for sig in STOP_SIGNALS if sig != signal.SIGINT}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold every stop signal while the block runs; one that arrived is delivered on exit.

    Uses ``pthread_sigmask`` (POSIX); elsewhere it holds nothing.
    """
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - Windows
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
