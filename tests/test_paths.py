"""Where the package finds its models and the shared data folder (installed or in a checkout)."""

from __future__ import annotations

from pathlib import Path

import pytest

from isf_robot import paths


def test_models_dir_holds_the_shipped_scenes() -> None:
    assert (paths.models_dir() / "panda_pole.xml").is_file()


def test_shared_data_env_variable_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(paths.DATA_ENV, str(tmp_path))
    assert paths.shared_data_dir() == tmp_path


def test_shared_data_found_from_the_working_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An installed package (no checkout beside it) run from a checkout finds ``../shared/data``."""
    data = tmp_path / "shared" / "data"
    data.mkdir(parents=True)
    (tmp_path / "main").mkdir()
    monkeypatch.delenv(paths.DATA_ENV, raising=False)
    monkeypatch.chdir(tmp_path / "main")
    fake_install = tmp_path / "site" / "pkgs" / "isf_robot" / "paths.py"
    monkeypatch.setattr(paths, "__file__", str(fake_install))
    assert paths.shared_data_dir() == data.resolve()
    (tmp_path / "main").rename(tmp_path / "elsewhere")
    monkeypatch.chdir(tmp_path / "elsewhere")
    data.rename(tmp_path / "shared" / "moved")
    # nothing found: the checkout-relative path is named (so the error shows a recognisable path)
    assert paths.shared_data_dir() == fake_install.resolve().parents[1].parent / "shared" / "data"


def test_satellite_default_shape_follows_the_data_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from satellite.shape.mesh_surface import default_shape_path

    monkeypatch.setenv(paths.DATA_ENV, str(tmp_path))
    assert default_shape_path() == tmp_path / "itokawa" / "itokawa_low.obj"
