"""Satellite orbit safety around asteroid Itokawa on the isf_robot core (paper, Sections III-IV).

The public names below are imported lazily (the project's one export style,
:func:`isf_robot._exports.lazy_exports`), so ``import satellite`` stays cheap.

Modules, bottom up: ``errors``; ``mesh`` (OBJ, exact moments) -> ``harmonics`` (coefficients of
a body) -> ``gravity_io`` (the table on disk) -> ``gravity`` (the field); ``model`` (orbit, band,
initial orbit), ``elements``; ``controller`` (safeguarding impulse and margin); ``shapes``,
``mesh_surface`` (body shapes) -> ``surface`` (the check); ``triggers`` (the choices and their
values) -> ``arcs`` (one integrated arc) -> ``policies`` (what each trigger does) -> ``simulate``
(a run); ``tau``, ``study``; the command line ``cli`` and ``cmd_*`` on top.

Typical use::

    from satellite import InitialOrbit, Trigger, simulate
    result = simulate(Trigger.GREEDY, hours=240.0, initial=InitialOrbit(seed=0))
"""

from __future__ import annotations

from isf_robot._exports import lazy_exports

_EXPORTS = {
    # gravity and shape
    "GravityField": "gravity", "load_default_field": "gravity",
    "polyhedron_harmonics": "harmonics", "PolyhedronHarmonics": "harmonics",
    "TriangleMesh": "mesh", "read_obj": "mesh",
    "SurfaceModel": "shapes", "EllipsoidSurface": "shapes",
    "MeshSurface": "mesh_surface", "load_surface": "mesh_surface", "body_mesh_info": "mesh_surface",
    "SurfaceCheck": "surface",
    # orbit model and controller
    "OrbitModel": "model", "BandBarrier": "model", "InitialOrbit": "model",
    "osculating_elements": "elements", "OrbitalElements": "elements",
    "SafeguardingController": "controller", "ControlParams": "controller", "resolve_control": "controller",
    "make_controller": "controller",
    # triggers and runs
    "Trigger": "triggers", "TRIGGERS": "triggers", "BandTriggers": "triggers",
    "IntegratorSettings": "arcs", "SatelliteSample": "arcs", "SimulationError": "arcs",
    "simulate": "simulate", "RunResult": "simulate",
    # tau_p
    "collect_tau": "tau", "fit_tau": "tau", "load_tau": "tau", "TauFit": "tau",
    # errors
    "SatelliteError": "errors", "MeshError": "errors", "GravityModelError": "errors",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
