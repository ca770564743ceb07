"""Where the MuJoCo shared library of the ``mujoco`` package is: the compiled kernels call its C functions."""

from __future__ import annotations

import glob
import os

import mujoco

__all__ = ["library_path"]


def library_path() -> str | None:
    """Path of the MuJoCo shared library the ``mujoco`` package loads (``None``: not found)."""
    folder = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found = sorted(glob.glob(os.path.join(folder, pattern)))
        if found:
            return found[0]
    return None
