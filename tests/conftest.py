"""Suite-wide: tests marked ``kernels`` compare the compiled kernels with the numpy path, so they skip under
``ISF_ROBOT_JIT=0`` (which turns the kernels off; the rest of the suite then tests the numpy path)."""

from __future__ import annotations

import os

import pytest


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if os.environ.get("ISF_ROBOT_JIT", "1").strip().lower() in ("0", "false", "no", "off"):
        skip = pytest.mark.skip(reason="ISF_ROBOT_JIT=0 turns off the compiled kernels this test compares")
        for item in items:
            if "kernels" in item.keywords:
                item.add_marker(skip)
