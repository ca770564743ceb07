"""Atomic text writes for the satellite's outputs.

The project's one implementation, :func:`isf_robot.core.files.write_text_atomic`, under its old import path.
"""

from __future__ import annotations

from isf_robot.support.files import write_text_atomic

__all__ = ["write_text_atomic"]
