"""The paired study: same starts for both triggers, gravity model and surface contact in every row."""

from __future__ import annotations

import json

from satellite.model import OrbitModel
from satellite.study import compare


def test_study_pairs_the_triggers_and_reports_contact(tmp_path) -> None:  # type: ignore[no-untyped-def]
    h_max = OrbitModel().h_max
    tau = tmp_path / "tau.json"
    tau.write_text(json.dumps({"format": "isf-satellite-tau/1", "fit": {"coef_s": [6000.0, 300.0], "h_max": h_max}}))
    out = compare([3], 6.0, str(tau), workers=1, gravity="sh8")
    assert out["gravity"] == "sh8" and len(out["rows"]) == 1
    row = out["rows"][0]
    assert row["seed"] == 3 and row["greedy"] >= 1 and row["maneuver"] >= 1
    assert row["greedy_surface_contacts"] is not None and row["maneuver_surface_contacts"] is not None
    assert row["greedy_min_h"] > 0 and row["maneuver_min_h"] > 0  # safety in both runs
    assert out["reduction"]["seeds"] == 1
