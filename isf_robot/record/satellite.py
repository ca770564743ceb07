"""Rerun content of a satellite run about Itokawa.

Logged, besides the base recorder's replay columns and events:

* ``/world/body``: the asteroid, spinning about body +z by the sample's ``body_angle``; the
  shape model (``itokawa_low.obj`` from the shared data folder, centred on its centre of
  mass) when it can be read, else an ellipsoid of the published dimensions
  535 x 294 x 209 m.
* ``/world/band/inner``, ``/world/band/outer``: the band's two spheres (1.6R and 2.4R).
* ``/world/satellite``: the current position; ``/world/trajectory/<k>``: the path, one
  static line strip per buffered block of samples (memory stays bounded).
* ``/world/impulses``: each impulse as an arrow at the satellite, labelled with its time.
* ``/plots/radius`` (``r/R``), ``/plots/barrier/h``, ``/plots/xi/xi``, ``/plots/xi/xi_tau``,
  ``/plots/mode`` (1 while the second impulse of a maneuver is pending).
* ``/replay/impulses``: every impulse's time, kind, index, ``dv`` (3), ``h``/``Xi`` after.

The replay "step" of a satellite run is an output sample: ``dt`` is the spacing to the
previous sample, ``on`` whether a maneuver is in progress, ``min_barrier`` the sample's ``h``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from .recorder import RerunRecorder
from .schema import IMPULSES

__all__ = ["SatelliteRecorder", "default_mesh_path", "read_shape", "ITOKAWA_HALF_AXES_M"]

ITOKAWA_HALF_AXES_M = (267.5, 147.0, 104.5)
"""Half axes of the stand-in ellipsoid [m]: Itokawa's published 535 x 294 x 209 m."""

_BAND = (1.6, 2.4)


def default_mesh_path() -> Path:
    """``<repo>/../shared/data/itokawa/itokawa_low.obj`` (outside the repository, never committed)."""
    repo = Path(__file__).resolve().parents[2]
    return repo.parent / "shared" / "data" / "itokawa" / "itokawa_low.obj"


_V = re.compile(r"^v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t]*$", re.M)
_F = re.compile(r"^f[ \t]+(\d+)(?:/\S*)?[ \t]+(\d+)(?:/\S*)?[ \t]+(\d+)(?:/\S*)?[ \t]*$", re.M)


def read_shape(path: Path, km: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The body's triangles for display, centred on the centre of mass of the enclosed volume.

    A fast path for plain triangle OBJ files (``v x y z`` and ``f i j k`` records, 1-based
    indices), a few times faster than the checked reader; anything else (polygons, negative
    indices, an open mesh) goes through :func:`satellite.mesh.read_obj`.

    Args:
        path: OBJ file.
        km: Coordinates in kilometres (the Gaskell model) rather than metres.

    Returns:
        ``(vertices [m] relative to the centre of mass, shape (V, 3); faces, shape (F, 3) uint32)``.

    """
    data = path.read_text(encoding="utf-8", errors="replace")
    v, f = _V.findall(data), _F.findall(data)
    n_v = sum(1 for line in data.splitlines() if line.startswith(("v ", "v\t")))
    n_f = sum(1 for line in data.splitlines() if line.startswith(("f ", "f\t")))
    if v and f and len(v) == n_v and len(f) == n_f:
        verts = np.asarray(v, dtype=np.float64) * (1000.0 if km else 1.0)
        faces = np.asarray(f, dtype=np.int64) - 1
        if faces.min() >= 0 and faces.max() < len(verts):
            a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
            vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0  # signed tetrahedra (origin, a, b, c)
            if vol.sum() > 0:
                com = (vol[:, None] * (a + b + c)).sum(axis=0) / (4.0 * vol.sum())
                return verts - com, faces.astype(np.uint32)
    from satellite.mesh import read_obj

    mesh = read_obj(path, units="km" if km else "m")
    return (np.asarray(mesh.vertices, dtype=np.float64) - np.asarray(mesh.centre_of_mass),
            np.asarray(mesh.faces, dtype=np.uint32))


def _impulse_columns(rows: list[tuple[Any, ...]]) -> Any:
    t, kind, index, dv, h_after, xi_after, interval = zip(*rows)
    dv_arr = np.asarray(dv, dtype=np.float64).reshape(len(rows), -1)
    return rr.AnyValues.columns(
        t=np.asarray(t, dtype=np.float64), kind=list(kind), index=np.asarray(index, dtype=np.int64),
        dv_x=dv_arr[:, 0], dv_y=dv_arr[:, 1] if dv_arr.shape[1] > 1 else np.zeros(len(rows)),
        dv_z=dv_arr[:, 2] if dv_arr.shape[1] > 2 else np.zeros(len(rows)),
        h_after=np.asarray(h_after, dtype=np.float64), xi_after=np.asarray(xi_after, dtype=np.float64),
        interval_s=np.asarray(interval, dtype=np.float64),
    )


class SatelliteRecorder(RerunRecorder):
    """Observer of ``satellite.simulate``: logs body, band, trajectory, triggers and impulses.

    Args:
        stream: The recording stream.
        radius_m: Itokawa's reference radius R [m]; default from the run info (``R_m``).
        mesh_path: Shape model (OBJ, km); default :func:`default_mesh_path`. When it is missing
            or unreadable the ellipsoid is drawn instead (see :attr:`body_shape`).
        arrow_scale: Arrow length per unit of delta-v [m per m/s]; default ``0.3 R / (0.1 m/s)``.
        capacity: Samples buffered per channel.
        close_on_finish: Close the stream in ``on_finish``.

    """

    kind = "satellite"
    CONTEXT_KEYS = ("radius_m", "mesh_path", "arrow_scale", "capacity")

    def __init__(
        self,
        stream: rr.RecordingStream,
        *,
        radius_m: float | None = None,
        mesh_path: str | Path | None = None,
        arrow_scale: float | None = None,
        capacity: int = 2048,
        close_on_finish: bool = True,
    ) -> None:
        super().__init__(stream, capacity=capacity, close_on_finish=close_on_finish)
        self.radius_m = radius_m
        self.mesh_path = Path(mesh_path) if mesh_path is not None else default_mesh_path()
        self.arrow_scale = arrow_scale
        self.body_shape = "none"
        self._t_prev: float | None = None
        self._pos = np.zeros((self.buffer.capacity, 3))
        self._n_pos = 0
        self._parts = 0
        self._last_pos: np.ndarray | None = None
        buf = self.buffer
        self._radius = buf.scalars("/plots/radius")
        self._h = buf.scalars("/plots/barrier/h")
        self._xi = buf.scalars("/plots/xi/xi")
        self._xi_tau = buf.scalars("/plots/xi/xi_tau")
        self._body = buf.channel("/world/body", {"quaternion": ((4,), np.float64)},
                                 lambda quaternion: rr.Transform3D.columns(quaternion=quaternion))
        self._sat = buf.channel("/world/satellite", {"positions": ((3,), np.float64)},
                                lambda positions: rr.Points3D.columns(positions=positions))
        self._impulses = buf.ragged(IMPULSES, _impulse_columns)

    @staticmethod
    def step_plots() -> tuple[tuple[str, Any], ...]:
        """Only ``/plots/mode`` (the barrier has its own series, ``/plots/barrier/h``)."""
        return RerunRecorder.step_plots()[:1]

    # -- static content --------------------------------------------------------------------
    def start_content(self, info: Mapping[str, Any]) -> None:
        """Body, band spheres and plot styles."""
        if self.radius_m is None:
            self.radius_m = float(info.get("R_m", 0.0)) or None
        if self.radius_m is None:
            from .errors import RecordError

            raise RecordError("SatelliteRecorder needs the reference radius: radius_m= or R_m in the run info")
        R = float(self.radius_m)
        if self.arrow_scale is None:
            self.arrow_scale = 0.3 * R / 0.1
        rec = self.stream
        rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._log_body()
        for name, k, color in (("inner", _BAND[0], (230, 120, 40, 60)), ("outer", _BAND[1], (40, 120, 230, 40))):
            rec.log(f"/world/band/{name}", rr.Ellipsoids3D(half_sizes=[[k * R] * 3], colors=[color],
                                                          fill_mode="majorwireframe",
                                                          labels=[f"{k}R"]), static=True)
        rec.log("/world/satellite", rr.Points3D.from_fields(radii=[0.03 * R], colors=[[250, 250, 60]]), static=True)
        rec.log("/plots/radius", rr.SeriesLines(names="r / R"), static=True)
        rec.log("/plots/barrier/h", rr.SeriesLines(names="h"), static=True)
        rec.log("/plots/xi/xi", rr.SeriesLines(names="Xi"), static=True)
        rec.log("/plots/xi/xi_tau", rr.SeriesLines(names="Xi_tau"), static=True)

    def _log_body(self) -> None:
        verts = faces = None
        try:
            if self.mesh_path.is_file():
                verts, faces = read_shape(self.mesh_path)
        except Exception:  # unreadable shape: the ellipsoid stands in (recorded in body_shape)
            verts = faces = None
        if verts is not None and faces is not None:
            self.stream.log("/world/body/shape", rr.Mesh3D(vertex_positions=verts, triangle_indices=faces,
                                                           albedo_factor=[150, 140, 120]), static=True)
            self.body_shape = f"mesh:{self.mesh_path.name}"
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
        self._radius.push(t, float(record.r) / R)
        self._h.push(t, float(record.h))
        self._xi.push(t, float(record.xi))
        self._xi_tau.push(t, float(record.xi_tau))
        half = 0.5 * float(record.body_angle)
        self._body.push(t, (0.0, 0.0, math.sin(half), math.cos(half)))
        self._sat.push(t, record.position)
        self._pos[self._n_pos] = record.position
        self._n_pos += 1
        if self._n_pos == self._pos.shape[0]:
            self._flush_trajectory()

    def _flush_trajectory(self) -> None:
        n = self._n_pos
        if n == 0:
            return
        pts = self._pos[:n]
        if self._last_pos is not None:
            pts = np.vstack([self._last_pos, pts])
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
            self.stream.set_time("sim_time", duration=t)
            self.stream.log("/world/impulses", rr.Arrows3D(
                origins=[x[:3]], vectors=[v * float(self.arrow_scale or 1.0)], colors=[[255, 60, 60]],
                labels=[f"{getattr(event, 'kind', '')} t = {t / 3600.0:.3f} h, |dv| = {mag:.3g} m/s"],
            ))
            self.stream.reset_time()
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

    def finish_content(self, summary: Mapping[str, Any]) -> None:
        """Flush the last trajectory block."""
        self._flush_trajectory()
