"""Layers point one way: ``cli -> {arm, satellite, record, plots} -> {support, core}`` (README.md, "Project layout").

Every import statement of every module is read (``ast``, relative imports resolved), so a
function-local import counts as much as a top-level one.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# package prefix of a module -> the project packages it must not import
FORBIDDEN = {
    "isf_robot.core": ("isf_robot.arm", "isf_robot.record", "isf_robot.cli", "isf_robot.plots", "isf_robot.support",
                       "satellite", "mujoco", "rerun", "scipy"),
    # pools, atomic files, report tables, install hints: beside the core, below every other layer
    "isf_robot.support": ("isf_robot.arm", "isf_robot.record", "isf_robot.cli", "isf_robot.plots", "satellite",
                          "mujoco", "rerun", "scipy"),
    "isf_robot.arm": ("isf_robot.record", "isf_robot.cli", "satellite", "rerun"),
    "isf_robot.record": ("isf_robot.arm", "isf_robot.cli", "satellite"),
    "satellite": ("isf_robot.arm", "isf_robot.record", "isf_robot.cli", "satellite.cli", "mujoco", "rerun"),
    # the satellite's command line is part of the cli layer: it may use the recorder, never the arm
    "satellite.cli": ("isf_robot.arm",),
    # static figures: the core's series in, matplotlib out; fed by the command line
    "isf_robot.plots": ("isf_robot.arm", "isf_robot.record", "isf_robot.cli", "satellite", "mujoco", "rerun"),
}


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
    return out


def _modules() -> list[Path]:
    return sorted(p for pkg in ("isf_robot", "satellite") for p in (ROOT / pkg).rglob("*.py"))


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down(path: Path) -> None:
    name = _module_name(path)
    layers = [p for p in FORBIDDEN if name == p or name.startswith(p + ".")]
    if not layers:
        return
    banned = FORBIDDEN[max(layers, key=len)]  # the most specific layer (satellite.cli within satellite)
    bad = sorted(i for i in _imports(path) for b in banned if i == b or i.startswith(b + "."))
    assert not bad, f"{name} imports {bad} (layers: cli -> {{arm, satellite, record}} -> core)"


def test_importing_the_core_loads_no_engine() -> None:
    code = (
        "import sys, importlib, pkgutil, isf_robot.core as c\n"
        # (not the optional compiled kernels, *_jit: numba itself imports scipy when it is installed;
        # the core loads them only when a filter is built, and runs without them)
        "for m in pkgutil.iter_modules(c.__path__):\n"
        "    if not m.name.endswith('_jit'): importlib.import_module('isf_robot.core.' + m.name)\n"
        "[getattr(c, n) for n in c.__all__]\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('mujoco', 'rerun', 'satellite', 'scipy'))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"the core loaded: {out.stdout.strip()}"
