"""Satellite orbit safety around asteroid Itokawa on the isf_robot core (paper, Sections III-IV).

The public names below are imported lazily (the project's one export style,
:func:`isf_robot._exports.lazy_exports`), so ``import satellite`` stays cheap.

Subpackages, bottom up (no module imports one above it): ``errors``; ``shape`` (meshes, the shipped
Itokawa mesh, surface models, the trajectory's surface check); ``gravity`` (spherical harmonics, the exact
polyhedron field, the tabulated field with its near-surface corrections, the models by name); ``orbit``
(the model and its band, elements, event location, arcs, compiled arcs, a run); ``control`` (triggers and
their policies, the impulsive and shooting controllers, ``tau_p``, the contact watch, the surface barrier);
``study`` (the paired study); the command line ``cli`` on top.

Typical use::

    from satellite import InitialOrbit, Trigger, simulate
    result = simulate(Trigger.GREEDY, hours=240.0, initial=InitialOrbit(seed=0))
"""

from __future__ import annotations

from isf_robot._exports import lazy_exports

_EXPORTS = {
    # gravity and shape
    "GravityField": "gravity.spherical", "load_default_field": "gravity.spherical",
    "polyhedron_harmonics": "gravity.harmonics", "PolyhedronHarmonics": "gravity.harmonics",
    "TriangleMesh": "shape.mesh", "read_obj": "shape.cache",
    "SurfaceModel": "shape.surfaces", "EllipsoidSurface": "shape.surfaces",
    "MeshSurface": "shape.mesh_surface", "load_surface": "shape.mesh_surface", "body_mesh_info": "shape.mesh_surface",
    "SurfaceCheck": "shape.surface_check",
    # orbit model and controller
    "OrbitModel": "orbit.model", "BandBarrier": "orbit.model", "InitialOrbit": "orbit.model",
    "osculating_elements": "orbit.elements", "OrbitalElements": "orbit.elements",
    "SafeguardingController": "control.controller", "ControlParams": "control.controller",
    "resolve_control": "control.controller", "make_controller": "control.controller",
    # triggers and runs
    "Trigger": "control.triggers", "TRIGGERS": "control.triggers", "BandTriggers": "control.triggers",
    "IntegratorSettings": "orbit.arcs", "SatelliteSample": "orbit.arcs", "SimulationError": "orbit.arcs",
    "simulate": "orbit.simulate", "RunResult": "orbit.simulate",
    # tau_p
    "collect_tau": "control.tau", "fit_tau": "control.tau", "load_tau": "control.tau", "TauFit": "control.tau",
    # errors
    "SatelliteError": "errors", "MeshError": "errors", "GravityModelError": "errors",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
