"""Satellite orbit safety around asteroid Itokawa on the isf_robot core (paper, Sections III-IV).

The public names below are imported lazily, so ``import satellite`` stays cheap.

Typical use::

    from satellite import InitialOrbit, simulate
    result = simulate("greedy", hours=240.0, initial=InitialOrbit(seed=0))
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    # gravity and shape
    "GravityField": "gravity", "load_default_field": "gravity", "polyhedron_harmonics": "gravity",
    "TriangleMesh": "mesh", "read_obj": "mesh",
    "MeshSurface": "surface", "EllipsoidSurface": "surface", "SurfaceCheck": "surface", "load_surface": "surface",
    # orbit model and controller
    "OrbitModel": "model", "BandBarrier": "model", "InitialOrbit": "model",
    "osculating_elements": "elements", "OrbitalElements": "elements",
    "SafeguardingController": "controller", "ControlParams": "controller", "resolve_control": "controller",
    "make_controller": "controller",
    # runs and tau_p
    "simulate": "simulate", "RunResult": "simulate", "SatelliteSample": "simulate", "TRIGGERS": "simulate",
    "collect_tau": "tau", "fit_tau": "tau", "load_tau": "tau", "TauFit": "tau",
    # errors
    "SatelliteError": "errors", "MeshError": "errors", "GravityModelError": "errors",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'satellite' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"satellite.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
