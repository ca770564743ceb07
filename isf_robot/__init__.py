"""isf_robot: event-triggered intermittent safety filters.

Layers: :mod:`isf_robot.core` (engine-free: numpy + qpsolvers), :mod:`isf_robot.arm`
(MuJoCo), :mod:`isf_robot.record` (Rerun). Importing this top-level package imports
nothing heavy.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
