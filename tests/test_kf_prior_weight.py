"""kf marks, one by one, the states whose posterior σ is above half their prior σ (the prior holds
a quarter or more of what is known of them), beside those left at 90 % of it (not determined):
psins19's 19-position filter on a six-position log leaves several so."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

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
    # the configuration's one filter starts every state from its prior σ: the ratio recomputed
    # from the result's σ and that prior marks exactly the states above half and up to 90 %
    from components.navigation.configs import load_config
    from components.navigation.kf import FilterSettings, prior_sigmas

    (stage,) = [st for st in load_config("psins19").stages if st.kind == "kf"]
    res = json.loads((tmp_path / "k.json").read_text())["parameters"]
    params = [q for q in res if q in (stage.parameters or res)]
    prior = dict(zip(params, prior_sigmas(params, FilterSettings(parameters=params, **stage.settings))))
    expected = {q for q in params if 0.5 < res[q]["sigma"] / prior[q] <= 0.9}
    assert set(ratios) == expected, (sorted(ratios), sorted(expected))
    for p, r in ratios.items():
        assert r == pytest.approx(res[p]["sigma"] / prior[p], rel=1e-9)
        assert p not in det["undetermined"]
        line = next(x for x in out.splitlines() if x.startswith(p + " "))
        assert "weakly determined" in line and f"{r:.0%}" in line, line
