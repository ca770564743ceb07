"""Regenerate the golden outputs of ``tests/golden/test_golden.py``.

Run from the repository root only when a behaviour change is intended and understood::

    python tests/golden/generate.py [CASE ...]    # e.g. satellite-greedy; default: every case

Each golden file is the ``--json`` output of one command line (``CASES`` in
``tests/golden/cases.py``), written as produced.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from cases import CASES, run_case  # noqa: E402


def main() -> None:
    names = sys.argv[1:] or list(CASES)
    unknown = [n for n in names if n not in CASES]
    if unknown:
        raise SystemExit(f"unknown case(s) {', '.join(unknown)}; valid: {', '.join(CASES)}")
    for name in names:
        argv = CASES[name]
        out = run_case(argv)
        (HERE / "data" / f"{name}.json").write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
        print(name, "written")


if __name__ == "__main__":
    main()
