"""Every file format's complete example (docs/formats.md) loads with calbench's own reader, and
what it loads is what the example says (issue 17, item 8)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORMATS = (ROOT / "docs" / "formats.md").read_text()


def _examples() -> dict[str, str]:
    """format name -> its example cell, from the table of docs/formats.md."""
    out = {}
    for line in FORMATS.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0] not in ("format", "---"):
            out[cells[0].split(" (")[0]] = cells[2]
    return out


def _path(cell: str) -> Path:
    return ROOT / re.search(r"`([^`]+)`", cell).group(1)


def test_the_table_lists_every_format():
    assert set(_examples()) == {"measurement log", "import mapping", "schedule", "scenario", "system",
                                "campaign", "calibration result", "noise"}


def test_log_example():
    from components.logs.logfile import read_log

    log = read_log(_path(_examples()["measurement log"]))
    meta = json.loads((ROOT / "examples/formats/log.json").read_text())
    assert log.n == 1000 and log.sample_rate_hz == meta["imu"]["sample_rate_hz"]
    assert log.axis_names == [a["name"] for a in meta["table"]["axes"]]


def test_mapping_example(tmp_path):
    from components.logs.mapping import load_mapping

    text = (ROOT / "docs" / "import.md").read_text()
    block = re.search(r"## A complete mapping\n```toml\n(.*?)```", text, re.S).group(1)
    (tmp_path / "m.toml").write_text(block)
    m = load_mapping(tmp_path / "m.toml")
    # the keys the example writes reach the mapping (a top-level key after a [table] header
    # would land in that table: the example had `exclude` inside [segments])
    assert m.exclude == [[120.0, 121.5], "pos07"]
    assert m.segments["rotX"] == {"kind": "rotation", "axis": "x", "angle_deg": 360}


def test_schedule_scenario_system_campaign_examples():
    from components.campaign.reader import load_campaign
    from components.control.schedule import load_schedule
    from components.simulation.scenario import load_scenario
    from orchestrator.loader import load_system

    ex = _examples()
    assert load_schedule(_path(ex["schedule"])).name
    sc = load_scenario(_path(ex["scenario"]))
    assert sc.imu_effects["acc.sf.z"] == pytest.approx(35e-6)       # "35 ppm" in the file
    assert load_system(_path(ex["system"])).name == "tumble"
    camp = load_campaign(_path(ex["campaign"]))
    assert camp.cases and camp.procedures and camp.systems


def test_result_and_noise_examples_belong_to_the_example_log():
    from components.diagnosis.noise_choice import load_noise_file
    from components.model.result import CalibrationResult, file_sha256

    ex = _examples()
    res = CalibrationResult.load(_path(ex["calibration result"]))
    assert res.effects == ["acc.bias", "gyro.bias"]
    # the result records the shipped log it was fitted to, by content
    assert res.data["csv_sha256"] == file_sha256(ROOT / "examples/formats/log.csv")
    noise = load_noise_file(_path(ex["noise"]))
    assert len(noise.channels) == 6
