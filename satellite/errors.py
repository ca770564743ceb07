"""Exceptions of the satellite package.

They derive from :class:`isf_robot.core.exceptions.ConfigError` (itself an
:class:`~isf_robot.core.exceptions.IsfError` and a :class:`ValueError`), so callers can catch
the project root, ``ValueError``, or the specific class.
"""

from __future__ import annotations

from isf_robot.core.exceptions import ConfigError

__all__ = ["SatelliteError", "MeshError", "GravityModelError"]


class SatelliteError(ConfigError):
    """Root of the errors raised on purpose by the satellite package."""


class MeshError(SatelliteError):
    """A shape file or triangle mesh is unreadable, open, non-manifold or badly oriented."""


class GravityModelError(SatelliteError):
    """A gravity model parameter or coefficient table is invalid (degree, mass, radius, shapes)."""
