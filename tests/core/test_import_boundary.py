import subprocess
import sys


def test_core_imports_neither_mujoco_nor_rerun():
    code = (
        "import sys, isf_robot.core, isf_robot.demo_core\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('mujoco', 'rerun', 'satellite'))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"core loaded: {out.stdout.strip()}"


def test_core_source_has_no_forbidden_imports():
    import pathlib

    import isf_robot.core as core

    root = pathlib.Path(core.__file__).parent
    for f in root.glob("*.py"):
        text = f.read_text()
        for bad in ("import mujoco", "import rerun", "from mujoco", "from rerun", "import scipy", "from scipy"):
            assert bad not in text, f"{f.name} contains {bad!r}"
