"""Stop signals, from a command's first instruction to its last file operation.

:func:`stop_signals` turns SIGTERM, SIGHUP, SIGQUIT and SIGUSR1 into ``KeyboardInterrupt`` (as
Ctrl-C already is), so a stop that arrives while a session is being opened, replayed or run
unwinds through the same clean path: the display zeroed, ``session_stopped`` logged when the
file is open, the file closed and checkpointed. :func:`signals_held` holds every stop signal
(SIGINT included) while a file operation must run whole (opening, logging the stop, closing):
a signal that arrives then is delivered right after it. SIGKILL cannot be caught; the file
format makes it harmless (see :mod:`.recording`).
"""

from __future__ import annotations

import contextlib
import os
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


#: signals that arrived while held (delivered, in order, when the outermost hold ends)
_PENDING: list[int] = []
_DEPTH = [0]


def _defer(signum, frame) -> None:
    _PENDING.append(signum)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold every stop signal while the block runs; one that arrived is delivered on exit.

    The hold is kept at Python level, not by the thread's signal mask: a process-directed signal
    (``kill PID``) may be taken by any thread that does not block it, such as the worker threads
    that scipy's FFT starts again in a forked child, and Python then runs its handler in the main
    thread whatever that thread's mask. So every stop signal gets a handler that only notes it;
    on exit the previous handlers come back and each noted signal is delivered to them: a Python
    handler is called (``KeyboardInterrupt`` from Ctrl-C's or :func:`stop_signals`'), a default
    action is re-sent to this process, an ignored signal stays ignored. Holds nest; outside the
    main thread (where Python cannot install handlers) it holds nothing.
    """
    if not _main_thread():
        yield
        return
    _DEPTH[0] += 1
    previous = {}
    if _DEPTH[0] == 1:
        for sig in STOP_SIGNALS:
            handler = signal.getsignal(sig)
            if handler is not signal.SIG_IGN:
                previous[sig] = handler
                signal.signal(sig, _defer)
    try:
        yield
    finally:
        _DEPTH[0] -= 1
        if _DEPTH[0] == 0:
            for sig, handler in previous.items():
                signal.signal(sig, signal.SIG_DFL if handler is None else handler)
            pending = [sig for sig in dict.fromkeys(_PENDING) if sig in previous]
            _PENDING.clear()
            for sig in pending:
                handler = previous[sig]
                if callable(handler):
                    handler(sig, None)
                elif handler in (signal.SIG_DFL, None):
                    os.kill(os.getpid(), sig)
