"""``isf-satellite gravity``: spherical-harmonic coefficients of a constant-density shape model."""

from __future__ import annotations

import argparse
import datetime
import hashlib
import sys
from pathlib import Path
from typing import Any

from satellite.errors import GravityModelError
from satellite.gravity.fine import FINE2_ZERO_M, add_fine_boxes, add_fine_level
from satellite.gravity.harmonics import G_CODATA2018, ITOKAWA_MASS_KG, MAX_DEGREE
from satellite.gravity.polyhedron import PolyhedronField
from satellite.gravity.spherical import GravityField
from satellite.gravity.table import GravityTable, TableGrid, build_table
from satellite.orbit.model import BAND_INNER
from satellite.shape.cache import read_obj
from satellite.shape.mesh import UNIT_SCALES
from satellite.shape.mesh_surface import MeshSurface

__all__ = ["KNOWN_SHAPES", "register", "run", "provenance_for"]

ITOKAWA_CITATION = (
    "Gaskell, R., Saito, J., Ishiguro, M., Kubota, T., Hashimoto, T., Hirata, N., Abe, S., "
    "Barnouin-Jha, O., and Scheeres, D., Gaskell Itokawa Shape Model V1.0, "
    "HAY-A-AMICA-5-ITOKAWASHAPE-V1.0, NASA Planetary Data System, 2008"
)

KNOWN_SHAPES: dict[str, dict[str, str]] = {
    "1879abcde28ca60f8616da212d6f7ae51dbc0cfc47ef271228d1bd2719b2a26b": {
        "name": "Itokawa, Gaskell shape model, 64 resolution level (itokawa_low.obj)",
        "citation": ITOKAWA_CITATION,
    },
}
"""Shape files recognised by sha256, whose citation is written into the provenance."""


def register(subparsers: Any) -> None:
    """Add the ``gravity`` subcommand to an ``argparse`` subparsers object."""
    parser = subparsers.add_parser(
        "gravity",
        help="compute a spherical-harmonic gravity table from a closed triangle mesh",
        description=(
            "Exact volume integration of the fully normalised (4-pi, no Condon-Shortley phase) "
            "spherical-harmonic coefficients of a constant-density body bounded by a closed, "
            "consistently oriented triangle mesh (Wavefront OBJ). Origin at the centre of mass, "
            "the mesh's axes, reference radius = volume-equivalent radius, GM = G * mass with "
            f"G = {G_CODATA2018:g}. Writes JSON with degree, r_ref_m, gm, C and S (rows C[n][m]) "
            "and a provenance record."
        ),
    )
    parser.add_argument(
        "--shape", required=True, metavar="PATH.obj", help="closed triangle mesh (OBJ)"
    )
    parser.add_argument(
        "--degree", type=int, metavar="N", help=f"degree and order, 0..{MAX_DEGREE} (spherical harmonics)"
    )
    parser.add_argument(
        "--table", action="store_true",
        help="instead: tabulate the exact polyhedron field on a shell grid over [1.5R, 2.5R] (.npz; the "
             "`--gravity table` model; a few ms of CPU per node)",
    )
    parser.add_argument("--n-lat", type=int, default=45, help="--table: latitude cells (default 45, 4 deg)")
    parser.add_argument("--n-r", type=int, default=17, help="--table: radial nodes (default 17)")
    parser.add_argument("--workers", type=int, default=1, help="--table: worker processes (default 1)")
    parser.add_argument("--near-cut", type=float, default=1.4, metavar="R_OVER_R",
                        help="--table: faces reaching above this radius (units of R) are tiled and summed exactly "
                             "near the surface (default 1.4; 0: the table alone)")
    parser.add_argument("--fine-step", type=float, default=4.0, metavar="M",
                        help="--table: node spacing of the fine boxes near the surface, metres (default 4; 0: none; "
                             "satellite.gravity.fine)")
    parser.add_argument("--refine-step", type=float, default=2.0, metavar="M",
                        help="--table: node spacing of a second level of boxes within 6 m of the surface in the band, "
                             "node values from the exact field, metres (default 2; 0: none)")
    parser.add_argument("--fine-from", metavar="TABLE.npz",
                        help="--table: instead of tabulating the shell again, read this table (of the same shape, "
                             "with its near-surface tiles) and add fine boxes to it")
    parser.add_argument(
        "--mass",
        type=float,
        default=ITOKAWA_MASS_KG,
        metavar="KG",
        help=f"body mass in kg (default {ITOKAWA_MASS_KG:g}, Itokawa, Fujiwara et al. 2006)",
    )
    parser.add_argument(
        "--units",
        choices=sorted(UNIT_SCALES),
        default="km",
        help="length unit of the OBJ coordinates (default km, as in the Gaskell model)",
    )
    parser.add_argument("--out", required=True, metavar="FILE", help="output file (.json; .npz with --table)")
    parser.set_defaults(func=run)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def provenance_for(
    shape: Path, degree: int, mass_kg: float, units: str, out: Path | None = None
) -> dict[str, Any]:
    """Provenance record of a table generated from ``shape``.

    Args:
        shape: The OBJ file.
        degree: Degree and order.
        mass_kg: Mass [kg].
        units: OBJ length unit.
        out: Output file, as given on the command line (for the generator command).

    Returns:
        JSON-ready mapping: shape file name and sha256 (with the data-set citation when the file
        is a known one), mass and G with sources, the generator command, and the UTC date.

    """
    sha = _sha256(shape)
    record: dict[str, Any] = {"shape_file": shape.name, "shape_sha256": sha}
    if sha in KNOWN_SHAPES:
        record["shape_model"] = KNOWN_SHAPES[sha]["name"]
        record["citation"] = KNOWN_SHAPES[sha]["citation"]
    record["mass_kg"] = mass_kg
    if mass_kg == ITOKAWA_MASS_KG:
        record["mass_source"] = "Fujiwara et al. 2006, Science 312:1330"
    record["G"] = G_CODATA2018
    record["G_source"] = "CODATA 2018"
    record["density"] = "constant"
    record["conventions"] = (
        "origin at the centre of mass, the mesh's own axes, r_ref = volume-equivalent radius, "
        "fully normalised (4-pi), no Condon-Shortley phase, U = GM/r sum (R/r)^n Pbar_nm "
        "(C cos m lambda + S sin m lambda), a = grad U"
    )
    record["generator"] = (
        f"isf-satellite gravity --shape {shape.as_posix()} --degree {degree} --mass {mass_kg:g} "
        f"--units {units} --out {out.as_posix() if out is not None else '<file>'}"
    )
    record["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d")
    return record


def run(args: argparse.Namespace) -> int:
    """Execute ``isf-satellite gravity`` with parsed arguments; return the exit status."""
    shape = Path(args.shape)
    if not shape.is_file():
        raise FileNotFoundError(f"shape file not found: {shape} (--shape takes an OBJ triangle mesh, e.g. Gaskell's "
                                "itokawa_low.obj)")
    if not args.mass > 0.0 or args.mass == float("inf"):
        raise GravityModelError(f"--mass must be a positive number of kg, got {args.mass:g}")
    if args.table:
        return _table(args, shape)
    if args.degree is None:
        raise GravityModelError("--degree N is required (or --table)")
    if not 0 <= args.degree <= MAX_DEGREE:
        raise GravityModelError(f"--degree must be in 0..{MAX_DEGREE}, got {args.degree}")
    field = GravityField.from_mesh(shape, args.degree, mass_kg=args.mass, units=args.units)
    out = Path(args.out)
    field.to_json(out, provenance=provenance_for(shape, args.degree, args.mass, args.units, out))
    print(
        f"wrote {out}: degree {field.degree}, r_ref {field.r_ref_m:.6g} m, "
        f"gm {field.gm:.6g} m^3/s^2",
        file=sys.stdout,
    )
    return 0


def _before_last_out(generator: str, options: str) -> str:
    """``generator`` (a command line, or several joined by ``;``) with ``options`` before its last ``--out``."""
    head, sep, tail = generator.rpartition(" --out ")
    return f"{head} {options}{sep}{tail}" if sep else f"{generator} {options}"


def _table(args: argparse.Namespace, shape: Path) -> int:
    """``isf-satellite gravity --table``: the exact field tabulated (see :mod:`satellite.gravity.table`)."""
    if args.n_lat < 4 or args.n_r < 4 or args.workers < 1:
        raise GravityModelError("--n-lat and --n-r must be >= 4 and --workers >= 1")
    if not 0.0 <= args.near_cut < 1.5:
        raise GravityModelError(f"--near-cut must be in [0, 1.5) (units of R; 0: no tiles), got {args.near_cut:g}")
    mesh = read_obj(shape, units=args.units)
    field = PolyhedronField.from_mesh(mesh, G_CODATA2018 * args.mass)
    r_ref = float(mesh.volume_equivalent_radius)
    grid = TableGrid(1.5 * r_ref, 2.5 * r_ref, args.n_r, args.n_lat)
    prov = provenance_for(shape, 0, args.mass, args.units, Path(args.out))
    prov["generator"] = (f"isf-satellite gravity --table --shape {shape.as_posix()} --mass {args.mass:g} "
                         f"--units {args.units} --n-lat {args.n_lat} --n-r {args.n_r} --near-cut {args.near_cut:g} "
                         f"--out {args.out}")
    prov["model"] = "exact constant-density polyhedron (Werner and Scheeres 1997), non-Kepler part tabulated"
    if args.near_cut > 0:
        prov["near_surface"] = (f"faces reaching above {args.near_cut:g} R tiled and summed exactly within 30-40 m "
                                "(satellite.gravity.near)")
    if not (args.fine_step == 0 or 0.5 <= args.fine_step <= 20.0):
        raise GravityModelError(f"--fine-step must be 0 (no fine boxes) or in [0.5, 20] m, got {args.fine_step:g}")
    if not (args.refine_step == 0 or 0.5 <= args.refine_step <= 10.0):
        raise GravityModelError(f"--refine-step must be 0 (no second level) or in [0.5, 10] m, "
                                f"got {args.refine_step:g}")
    if args.refine_step > 0 and args.fine_step == 0 and not args.fine_from:
        raise GravityModelError("--refine-step needs a table with fine boxes (--fine-step > 0, or --fine-from a "
                                "table that has them)")
    if args.fine_from:
        table = GravityTable.load(args.fine_from)
        if abs(table.r_ref_m - r_ref) > 1e-6 * r_ref or abs(table.gm - field.gm) > 1e-9 * field.gm:
            raise GravityModelError(f"--fine-from {args.fine_from}: R or GM differ from the shape's "
                                    f"({table.r_ref_m:.6g} m, {table.gm:.6g} vs {r_ref:.6g} m, {field.gm:.6g})")
        grid = table.grid
        prov = {**table.provenance, "date": prov["date"]}
        prov["generator"] += (f" ; then isf-satellite gravity --table --shape {shape.as_posix()} "
                              f"--fine-from {args.fine_from} --out {args.out}")
    else:
        table = build_table(field, grid, r_ref, workers=args.workers, provenance=prov,
                            near_cut=args.near_cut * r_ref if args.near_cut > 0 else None)
    if args.fine_step > 0:

        add_fine_boxes(table, field, MeshSurface(mesh), step=args.fine_step, workers=args.workers,
                       log=lambda line: print(line, file=sys.stderr, flush=True))
        prov["fine_boxes"] = (f"Cartesian B-spline boxes, {args.fine_step:g} m nodes, within 35 m of the surface, "
                              "exterior field continued inside (satellite.gravity.fine)")
    if args.refine_step > 0:

        if table.fine is None:
            raise GravityModelError("--refine-step needs a table with fine boxes (--fine-step > 0, or --fine-from a "
                                    "table that has them)")
        n_first = len(table.fine)
        add_fine_level(table, field, MeshSurface(mesh), step=args.refine_step, r_band=BAND_INNER * r_ref,
                       workers=args.workers, log=lambda line: print(line, file=sys.stderr, flush=True))
        if len(table.fine) == n_first:
            print("no second level: the surface stays below the band", file=sys.stderr)
        prov["fine_boxes_2"] = (f"second level: {args.refine_step:g} m nodes within {FINE2_ZERO_M:g} m of the surface "
                                "at r >= 1.6 R, from the exact field (satellite.gravity.fine.add_fine_level)")
    prov["generator"] = _before_last_out(prov["generator"], f"--fine-step {args.fine_step:g} "
                                         f"--refine-step {args.refine_step:g}")
    table.provenance = prov
    table.save(args.out)
    print(f"wrote {args.out}: {grid.n_r} x {grid.n_lat} x {grid.n_lon} nodes, r in [{grid.r_lo:.6g}, "
          f"{grid.r_hi:.6g}] m", file=sys.stdout)
    return 0
