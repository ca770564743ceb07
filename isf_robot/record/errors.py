"""Exceptions of the Rerun layer.

Both derive from :class:`isf_robot.core.exceptions.ConfigError` (an
:class:`~isf_robot.core.exceptions.IsfError` and a :class:`ValueError`), so the command lines
report them as one-line user errors.
"""

from __future__ import annotations

from pathlib import Path

from isf_robot.core.exceptions import ConfigError

__all__ = ["RecordError", "RecordingReadError", "ViewerUnavailableError"]


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
