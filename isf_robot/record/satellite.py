"""Rerun content of a satellite run about Itokawa.

Logged, besides the base recorder's replay columns and events:

* ``/world/body``: the asteroid, spinning about body +z by the sample's ``body_angle``; the
  triangles the run sends in its start info (``body_mesh``: ``vertices`` (N, 3) [m] about the
  centre of mass, ``faces`` (M, 3), ``name``) when it sends them, else an ellipsoid of the
  published dimensions 535 x 294 x 209 m. The recorder reads no shape file itself: the run
  tells its observers what to draw.
* ``/world/band/inner``, ``/world/band/outer``: the band's two spheres (1.6R and 2.4R).
* ``/world/satellite``: the current position; ``/world/trajectory/<k>``: the path, one
  static line strip per buffered block of samples (memory stays bounded).
* ``/world/impulses``: each impulse as an arrow at the satellite, labelled with its time.
* ``/plots/radius`` (``r/R``) with ``/plots/radius/band_inner`` and ``/plots/radius/band_outer``
  (the band's edges, from the start info's ``band_over_R``), ``/plots/barrier/h``,
  ``/plots/xi/xi``, ``/plots/xi/xi_tau``.
* ``/plots/impulses/dv``: one marker per impulse at its ``|dv|`` [m/s] (every trigger, greedy
  included), and ``/plots/impulses/maneuver`` (1 while the second impulse of a maneuver is
  pending).
* ``/replay/impulses``: every impulse's time, kind, index, ``dv`` (3), ``h``/``Xi`` after.

The default layout is sent again at the start with every plot's time axis spanning the
requested run (``hours``). Replay takes the run's exact figures (``min_h``, ``r_min_over_R``,
...) from the logged summary: the samples are spaced ``sample_interval_s`` apart and miss the
extremes between them.

The replay "step" of a satellite run is an output sample: ``dt`` is the spacing to the
previous sample, ``on`` whether a maneuver is in progress, ``min_barrier`` the sample's ``h``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

from .blueprints import satellite_blueprint
from .errors import RecordError
from .recorder import RerunRecorder, value_columns
from .schema import IMPULSES, PLOTS

__all__ = ["SatelliteRecorder", "body_triangles", "ITOKAWA_HALF_AXES_M"]

ITOKAWA_HALF_AXES_M = (267.5, 147.0, 104.5)
"""Half axes of the stand-in ellipsoid [m]: Itokawa's published 535 x 294 x 209 m."""

_BAND = (1.6, 2.4)


def body_triangles(mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    """Check the ``body_mesh`` entry of a run's start info and return its triangles.

    Args:
        mesh: Mapping with ``vertices`` (N, 3) [m] and ``faces`` (M, 3) (0-based vertex indices).

    Returns:
        ``(vertices float64 (N, 3), faces uint32 (M, 3))``.

    Raises:
        RecordError: Not such a mapping (missing keys, wrong shapes, non-finite vertices, indices
            out of range).

    """
    try:
        verts = np.asarray(mesh["vertices"], dtype=np.float64)
        faces = np.asarray(mesh["faces"])
    except (KeyError, TypeError, ValueError) as exc:
        raise RecordError(f"body_mesh must map 'vertices' (N, 3) and 'faces' (M, 3) to arrays ({exc})") from None
    if verts.ndim != 2 or verts.shape[1] != 3 or not len(verts) or not np.isfinite(verts).all():
        raise RecordError(f"body_mesh vertices must be finite, shape (N, 3); got shape {verts.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or not len(faces) or faces.dtype.kind not in "iu":
        raise RecordError(f"body_mesh faces must be integers, shape (M, 3); got {faces.dtype} {faces.shape}")
    if faces.min() < 0 or faces.max() >= len(verts):
        raise RecordError(f"body_mesh faces index vertices 0..{len(verts) - 1}; got {faces.min()}..{faces.max()}")
    return verts, faces.astype(np.uint32)


def _arrow_columns(origins: np.ndarray, vectors: np.ndarray, labels: np.ndarray) -> Any:
    """One arrow per row (the impulse at the satellite), labelled."""
    return rr.Arrows3D.columns(origins=origins, vectors=vectors, labels=[str(x) for x in labels])


def _impulse_columns(rows: list[tuple[Any, ...]]) -> Any:
    t, kind, index, dv, h_after, xi_after, interval = zip(*rows)
    dv_arr = np.asarray(dv, dtype=np.float64).reshape(len(rows), -1)
    return value_columns(
        t=np.asarray(t, dtype=np.float64), kind=kind, index=np.asarray(index, dtype=np.int64),
        dv_x=dv_arr[:, 0], dv_y=dv_arr[:, 1] if dv_arr.shape[1] > 1 else np.zeros(len(rows)),
        dv_z=dv_arr[:, 2] if dv_arr.shape[1] > 2 else np.zeros(len(rows)),
        h_after=np.asarray(h_after, dtype=np.float64), xi_after=np.asarray(xi_after, dtype=np.float64),
        interval_s=np.asarray(interval, dtype=np.float64),
    )


class SatelliteRecorder(RerunRecorder):
    """Observer of :func:`satellite.orbit.simulate.simulate`: logs body, band, trajectory, triggers and impulses.

    Args:
        stream: The recording stream.
        radius_m: Itokawa's reference radius R [m]; default from the run info (``R_m``).
        arrow_scale: Arrow length per unit of delta-v [m per m/s]; default ``0.3 R / (0.1 m/s)``.
        capacity: Samples buffered per channel.
        close_on_finish: Close the stream in ``on_finish``.

    """

    kind = "satellite"
    CONTEXT_KEYS = ("radius_m", "arrow_scale", "capacity")
    INFO_OBJECTS = ("body_mesh",)

    def __init__(
        self,
        stream: rr.RecordingStream,
        *,
        radius_m: float | None = None,
        arrow_scale: float | None = None,
        capacity: int = 2048,
        close_on_finish: bool = True,
    ) -> None:
        super().__init__(stream, capacity=capacity, close_on_finish=close_on_finish)
        self.radius_m = radius_m
        self.arrow_scale = arrow_scale
        self.body_shape = "none"
        self._t_prev: float | None = None
        self._pos = np.zeros((self.buffer.capacity, 3))
        self._n_pos = 0
        self._parts = 0
        self._last_pos: np.ndarray | None = None
        buf = self.buffer
        scalars = (lambda name: lambda t, a: (t, rr.Scalars.columns(scalars=a[name])))
        # one push per sample feeds every per-sample entity (one channel, its rows sent to each path)
        self._sample = buf.channel("/plots/radius", {
            "r": ((), np.float64), "h": ((), np.float64), "xi": ((), np.float64), "xi_tau": ((), np.float64),
            "quaternion": ((4,), np.float64), "position": ((3,), np.float64)},
            lambda r, **_: rr.Scalars.columns(scalars=r), derived=(
                ("/plots/barrier/h", scalars("h")), ("/plots/xi/xi", scalars("xi")),
                ("/plots/xi/xi_tau", scalars("xi_tau")),
                ("/world/body", lambda t, a: (t, rr.Transform3D.columns(quaternion=a["quaternion"]))),
                ("/world/satellite", lambda t, a: (t, rr.Points3D.columns(positions=a["position"]))),
            ))
        self._impulses = buf.ragged(IMPULSES, _impulse_columns)
        self._arrows = buf.channel("/world/impulses", {"origins": ((3,), np.float64), "vectors": ((3,), np.float64),
                                                       "labels": ((), object)}, _arrow_columns)
        self._dv = buf.scalars(f"{PLOTS}/impulses/dv")
        self._band = _BAND
        self._t_last = 0.0

    @staticmethod
    def step_plots() -> tuple[tuple[str, Any], ...]:
        """Only the maneuver phase, ``/plots/impulses/maneuver`` (the barrier has ``/plots/barrier/h``)."""
        return ((f"{PLOTS}/impulses/maneuver", RerunRecorder.step_plots()[0][1]),)

    # -- static content --------------------------------------------------------------------
    def start_content(self, info: Mapping[str, Any]) -> None:
        """Body, band spheres and plot styles."""
        if self.radius_m is None:
            self.radius_m = float(info.get("R_m", 0.0)) or None
        if self.radius_m is None:
            raise RecordError("SatelliteRecorder needs the reference radius: radius_m= or R_m in the run info")
        R = float(self.radius_m)
        if self.arrow_scale is None:
            self.arrow_scale = 0.3 * R / 0.1
        rec = self.stream
        rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._log_body(info)
        for name, k, color in (("inner", _BAND[0], (230, 120, 40, 60)), ("outer", _BAND[1], (40, 120, 230, 40))):
            rec.log(f"/world/band/{name}", rr.Ellipsoids3D(half_sizes=[[k * R] * 3], colors=[color],
                                                          fill_mode="majorwireframe",
                                                          labels=[f"{k}R"]), static=True)
        rec.log("/world/satellite", rr.Points3D.from_fields(radii=[0.03 * R], colors=[[250, 250, 60]]), static=True)
        rec.log("/world/impulses", rr.Arrows3D.from_fields(colors=[[255, 60, 60]]), static=True)
        rec.log("/plots/radius", rr.SeriesLines(names="r / R"), static=True)
        band = info.get("band_over_R") or _BAND
        self._band = (float(band[0]), float(band[1]))
        for name, k in zip(("band_inner", "band_outer"), self._band):
            rec.log(f"/plots/radius/{name}", rr.SeriesLines(names=f"{k:g} R", colors=[[150, 150, 150]],
                                                            widths=[1.0]), static=True)
        self._band_lines(0.0)
        rec.log("/plots/impulses/dv", rr.SeriesPoints(names="|dv| [m/s]", colors=[[255, 60, 60]],
                                                      markers=["diamond"], marker_sizes=[4.0]), static=True)
        rec.log("/plots/impulses/maneuver", rr.SeriesLines(names="maneuver pending (1)"), static=True)
        hours = info.get("hours")
        if isinstance(hours, (int, float)) and hours > 0:
            rec.send_blueprint(satellite_blueprint(duration_s=3600.0 * float(hours)), make_active=True,
                               make_default=True)
        rec.log("/plots/barrier/h", rr.SeriesLines(names="h"), static=True)
        rec.log("/plots/xi/xi", rr.SeriesLines(names="Xi"), static=True)
        rec.log("/plots/xi/xi_tau", rr.SeriesLines(names="Xi_tau"), static=True)

    def _log_body(self, info: Mapping[str, Any]) -> None:
        """The body from the start info's ``body_mesh`` (see :func:`body_triangles`), else the ellipsoid."""
        mesh = info.get("body_mesh")
        if mesh is not None:
            verts, faces = body_triangles(mesh)
            self.stream.log("/world/body/shape", rr.Mesh3D(vertex_positions=verts, triangle_indices=faces,
                                                           albedo_factor=[150, 140, 120]), static=True)
            self.body_shape = f"mesh:{mesh.get('name', 'body')}"
        else:
            self.stream.log("/world/body/shape", rr.Ellipsoids3D(half_sizes=[ITOKAWA_HALF_AXES_M],
                                                                 colors=[[150, 140, 120]], fill_mode="solid"),
                            static=True)
            self.body_shape = "ellipsoid"
        self.stream.log("/run/body_shape", rr.AnyValues(body_shape=self.body_shape), static=True)

    # -- per sample --------------------------------------------------------------------------
    def replay_row(self, record: Any) -> tuple[float, float, bool, float, bool, float]:
        """Sample -> ``(t, spacing, maneuver pending, 0, False, h)``."""
        t = float(record.t)
        dt = 0.0 if self._t_prev is None else t - self._t_prev
        self._t_prev = t
        on = str(record.phase).startswith("second")
        return (t, dt, on, 0.0, False, float(record.h))

    def step_content(self, t: float, record: Any) -> None:
        """Radius, barrier, triggers, body spin, position and trajectory."""
        R = float(self.radius_m or 1.0)
        self._t_last = t
        half = 0.5 * float(record.body_angle)
        self._sample.push(t, float(record.r) / R, record.h, record.xi, record.xi_tau,
                          (0.0, 0.0, math.sin(half), math.cos(half)), record.position)
        self._pos[self._n_pos] = record.position
        self._n_pos += 1
        if self._n_pos == self._pos.shape[0]:
            self._flush_trajectory()

    def _flush_trajectory(self) -> None:
        n = self._n_pos
        if n == 0:
            return
        pts = self._pos[:n].copy()  # (the buffer fills again before the stream may have encoded it)
        if self._last_pos is not None:
            pts = np.vstack([self._last_pos, pts])
        self._band_lines(self._t_last)
        self.stream.log(f"/world/trajectory/{self._parts:05d}",
                        rr.LineStrips3D([pts], colors=[[250, 250, 60]],
                                        radii=[0.004 * float(self.radius_m or 1.0)]), static=True)
        self._last_pos = self._pos[n - 1].copy()
        self._parts += 1
        self._n_pos = 0

    def event_content(self, t: float, event: Any) -> None:
        """An arrow for the impulse and its structured row."""
        v = np.asarray(getattr(event, "v", np.zeros(3)), dtype=np.float64).ravel()
        x = np.asarray(getattr(event, "x_before", np.zeros(6)), dtype=np.float64).ravel()
        if v.size == 3 and x.size >= 3:
            mag = float(np.linalg.norm(v))
            self._arrows.push(t, x[:3], v * float(self.arrow_scale or 1.0),
                              f"{getattr(event, 'kind', '')} t = {t / 3600.0:.3f} h, |dv| = {mag:.3g} m/s")
        self._dv.push(t, float(np.linalg.norm(v[:3])) if v.size >= 3 else float("nan"))
        self._impulses.push(t, (t, str(getattr(event, "kind", "")), int(getattr(event, "index", 0)),
                                tuple(v[:3]) if v.size >= 3 else (float("nan"),) * 3,
                                float(getattr(event, "h_after", float("nan"))),
                                float(getattr(event, "xi_after", float("nan"))),
                                float(getattr(event, "interval_s", float("nan")))))

    def describe_event(self, event: Any) -> str:
        """``t = 12.345 h: greedy impulse #3, |dv| = 0.0123 m/s``."""
        v = np.asarray(getattr(event, "v", np.zeros(1)), dtype=float)
        return (f"t = {float(event.t) / 3600.0:.4f} h: {getattr(event, 'kind', '')} impulse "
                f"#{getattr(event, 'index', '?')}, |dv| = {float(np.linalg.norm(v)):.4g} m/s")

    def _band_lines(self, t: float) -> None:
        """A point of each band edge's constant line at ``t`` (sent at the start and with each block)."""
        self.stream.set_time("sim_time", duration=t)
        for name, k in zip(("band_inner", "band_outer"), self._band):
            self.stream.log(f"/plots/radius/{name}", rr.Scalars(k))
        self.stream.reset_time()

    def finish_content(self, summary: Mapping[str, Any]) -> None:
        """Flush the last trajectory block (and close the band lines at the last sample)."""
        self._flush_trajectory()
        self._band_lines(self._t_last)
