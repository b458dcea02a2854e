"""The experimenter's progress bar, kept off the subject's screen.

A bar over trials shows the running estimate (a threshold, the models' probabilities): that is
for the experimenter. A subject who sees it learns where the procedure thinks their threshold is,
and a bar drawn on the terminal where the subject answers also lands on the same line as the
response prompt. So the bar goes to the experimenter's stream (standard error by default) only
when that stream is not the subject's screen (:meth:`ResponseSource.on_screen`): with
``--responses terminal`` in one terminal there is no bar (one line says how to follow the
session instead: ``tactilab experiment status`` from another terminal, or standard error
redirected there); with standard error redirected (``2>/dev/pts/3``, ``2>progress.log``) or a
simulated observer, the bar with the estimate goes to standard error.
"""

from __future__ import annotations

import sys
from typing import TextIO


class NoBar:
    """The bar's interface, doing nothing (no tqdm object at all: even a disabled one starts a
    monitor thread)."""

    def update(self, n: int) -> None:
        pass

    def set_postfix_str(self, text: str) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(responses, *, total: int, initial: int, desc: str, session_path, stream: TextIO | None = None):
    """A tqdm bar on ``stream``, or :class:`NoBar` when ``stream`` is the subject's screen.

    Parameters
    ----------
    responses : ResponseSource
        Where responses come from; its :meth:`on_screen` says whether the subject sees ``stream``.
    total, initial : int
        Trials planned, trials already done.
    desc : str
        The bar's label (subject and session codes).
    session_path : str or Path
        The session file, named in the line that replaces the bar on the subject's screen.
    stream : file object, optional
        The experimenter's stream (default ``sys.stderr``, read when called).
    """
    stream = sys.stderr if stream is None else stream
    if responses.on_screen(stream):
        stream.write(f"progress: not shown on the subject's screen; follow it with `tactilab experiment status "
                     f"{session_path}` from another terminal, or redirect standard error there\n")
        stream.flush()
        return NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, unit="trial", desc=desc, file=stream)
