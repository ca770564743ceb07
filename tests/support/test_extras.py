"""The extras hints: one wording, right for a wheel user and for a checkout, everywhere."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib

from isf_robot.support.extras import EXTRAS, install_hint
from isf_robot.support.parallel import RAY_MISSING

ROOT = Path(__file__).resolve().parents[2]


def test_extras_are_the_distributions() -> None:
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert set(EXTRAS) == set(meta["project"]["optional-dependencies"])
    assert install_hint("plots") == "pip install 'isf-robot[plots]' (or pip install '.[plots]' from a checkout)"
    with pytest.raises(ValueError, match="unknown extra 'plot'; valid: plots, ray"):
        install_hint("plot")


def test_every_hint_in_code_and_readme_names_both_ways() -> None:
    from isf_robot.plots.output import PlotsUnavailableError  # noqa: F401 (the module builds its message)

    assert install_hint("ray") in RAY_MISSING
    sources = [p for d in ("isf_robot", "satellite") for p in (ROOT / d).rglob("*.py")] + [ROOT / "README.md"]
    bare = []
    for p in sources:
        text = p.read_text()
        if p.suffix == ".md":  # the README's fenced commands are a checkout's own (clone, then install "."): not hints
            text = re.sub(r"```.*?```", "", text, flags=re.S)
        for line in text.splitlines():
            # every written-out `pip install <something>[extra]` must be the wheel form next to the checkout form
            for m in re.finditer(r"pip install ['\"]?(isf-robot|\.)\[(\w+)\]", line):
                other = ".[" if m.group(1) == "isf-robot" else "isf-robot["
                if other + m.group(2) + "]" not in line:
                    bare.append(f"{p.relative_to(ROOT)}: {line.strip()}")
    assert bare == []
