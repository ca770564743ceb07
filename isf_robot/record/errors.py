"""Exceptions of the Rerun layer.

Both derive from :class:`isf_robot.core.exceptions.ConfigError` (an
:class:`~isf_robot.core.exceptions.IsfError` and a :class:`ValueError`), so the command lines
report them as one-line user errors.
"""

from __future__ import annotations

from pathlib import Path

from isf_robot.core.exceptions import ConfigError

__all__ = ["RecordError", "RecordingReadError", "ViewerUnavailableError", "defer_error", "take_deferred_errors"]


class RecordError(ConfigError):
    """Root of the errors raised on purpose by :mod:`isf_robot.record`."""


class ViewerUnavailableError(RecordError):
    """``--spawn`` was asked for but no Rerun viewer can start here (no executable, no display)."""


class RecordingReadError(RecordError):
    """A ``.rrd`` file is missing, truncated, corrupt, not a Rerun file, or lacks the replay data.

    Attributes:
        path: The file that could not be read.
        reason: What is wrong with it.

    """

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path = Path(path)
        self.reason = reason
        super().__init__(f"cannot replay {str(self.path)!r}: {reason}")


_DEFERRED: list[RecordError] = []


def defer_error(exc: RecordError) -> None:
    """Keep a recording failure found when a run finished (e.g. the disk filled up).

    A recorder's ``on_finish`` must not lose the run's results for a failed file, so it keeps the
    error here instead of raising it; the command line reports it after printing the results
    (:func:`isf_robot.cli.errors.run_handler`, exit status 2). Library users find it on the
    recorder's ``error`` attribute and here.
    """
    _DEFERRED.append(exc)


def take_deferred_errors() -> list[RecordError]:
    """Return and forget the recording failures kept by :func:`defer_error`."""
    out = list(_DEFERRED)
    _DEFERRED.clear()
    return out
