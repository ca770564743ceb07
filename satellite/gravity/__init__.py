"""Gravity of the body: spherical harmonics, the exact polyhedron field, the tabulated field and its corrections."""
