"""kf marks, one by one, the states whose posterior σ is above half their prior σ (the prior holds
a quarter or more of what is known of them), beside those left at 90 % of it (not determined):
psins19's 19-position filter on a six-position log leaves several so."""
from __future__ import annotations

import json
from pathlib import Path

from components.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_states_the_prior_still_weighs_on_are_marked(tmp_path, capsys):
    scn = ROOT / "examples" / "scenarios" / "six_position.toml"
    assert main(["simulate", str(scn), "--out", str(tmp_path / "six"), "--dwell", "20"]) == 0
    capsys.readouterr()
    main(["kf", "psins19", str(tmp_path / "six"), "--out", str(tmp_path / "k.json"), "--quiet"])
    out = capsys.readouterr().out
    det = json.loads((tmp_path / "k.json").read_text())["determinability"]
    ratios = det["posterior_to_prior_sigma"]
    assert ratios and set(det["weakly_determined"]) == set(ratios)
    for p, r in ratios.items():
        assert 0.5 < r <= 0.9, (p, r)
        assert p not in det["undetermined"]
        line = next(x for x in out.splitlines() if x.startswith(p + " "))
        assert "weakly determined" in line and f"{r:.0%}" in line, line
