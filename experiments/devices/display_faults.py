"""When a stimulus did not reach the display as commanded: :func:`display_fault` and :class:`DisplayFault`.

The runner asks :func:`display_fault` about every interval's playback report; a fault stops the
trial unscored (docs/experiments.md).
"""

from __future__ import annotations

from typing import Any

from .display import DisplayError, PlaybackReport

#: Fraction of a stimulus's frames that may go unacknowledged (a lost datagram on a busy link)
#: before the trial is a display fault; any non-``applied`` acknowledgement is a fault at once.
MAX_UNACKED_FRACTION = 0.01


class DisplayFault(DisplayError):
    """A stimulus did not reach the display as commanded; the trial was not scored."""


def display_fault(report: PlaybackReport) -> dict[str, Any] | None:
    """Why one interval's playback cannot be scored, or None when it reached the display.

    Returns
    -------
    dict or None
        ``reason`` (text), ``alarm`` (True for ``stale`` acknowledgements and foreign frames),
        and the counts ``frames_sent``, ``stale``, ``rejected`` (non-``applied``
        acknowledgements), ``unacknowledged`` and ``foreign`` (frames the device applied that this
        host did not send).
    """
    counts = {"frames_sent": report.frames_sent, "stale": report.stale, "rejected": report.rejected,
              "unacknowledged": report.unacknowledged, "skipped": report.skipped, "stopped": report.stopped,
              "foreign": report.foreign}
    allowed = int(MAX_UNACKED_FRACTION * report.frames_sent)
    if report.foreign:
        reason = foreign_reason(report.foreign)
    elif report.stale:
        reason = (f"ALARM: {report.stale} of {report.frames_sent} frames were acknowledged 'stale': the "
                  "device had applied newer sequence numbers, so another sender is driving it")
    elif report.rejected:
        reason = f"{report.rejected} of {report.frames_sent} frames were refused by the device"
    elif report.unacknowledged > allowed:
        reason = (f"{report.unacknowledged} of {report.frames_sent} frames were never acknowledged (at most "
                  f"{allowed} = {MAX_UNACKED_FRACTION:.0%} may be)")
    elif report.stopped:
        reason = (f"playback stopped after {report.frames_sent} frames, before the end of the stimulus"
                  + (f" ({report.skipped} frames were due more than half a period ago and skipped: the host "
                     "could not keep the frame rate)" if report.skipped else ""))
    else:
        return None
    return {"reason": reason, "alarm": bool(report.stale or report.foreign), **counts}


def foreign_reason(n: int) -> str:
    """Why frames another process made the device apply fault the trial."""
    return (f"ALARM: the device applied {n} frames this host did not send (its frames_applied counter moved "
            "between this host's frames): another process drove the display")
