"""Schedules: TOML parsing into dataclasses, ready-made schedules, and every error."""
import math

import pytest

from components.control.schedule import (
    COUNTS_PER_REV,
    DEG,
    Dwell,
    Index,
    Rate,
    Rotate,
    available_schedules,
    load_schedule,
    loads_schedule,
)
from components.errors import ScheduleError

GOOD = """
[schedule]
name = "demo"
[parameters]
dwell = 12.0
turns = 2
rate = 10.0
[settings]
settle_hold = 1.0
index_timeout = 30.0
settle_tol_deg = 0.001
[[steps]]
kind = "index"
angles_deg = [0, 90, 0]
label = "a"
[[steps]]
kind = "dwell"
duration = "$dwell"
label = "a"
[[steps]]
kind = "rotate"
axis = "outer"
rate_dps = "-$rate"
turns = "$turns"
[[steps]]
kind = "rate"
axis = 2
rate_dps = 30
duration = 4
[[steps]]
kind = "tumble"
attitudes_deg = [[0, 0, 0], [0, 180, 0]]
dwell = 5
[[steps]]
kind = "repeat"
times = 2
[[steps.steps]]
kind = "tumble"
attitudes_deg = [[90, 0, 0]]
dwell = 1
"""


def test_parse_units_labels_and_expansion():
    s = loads_schedule(GOOD, "demo.toml")
    assert s.name == "demo"
    assert s.settings.settle_hold == 1.0 and s.settings.index_timeout == 30.0
    assert s.settings.settle_tol == pytest.approx(0.001 * DEG)
    assert s.settings.settle_rate_tol == 1e-5
    st = s.steps
    assert isinstance(st[0], Index) and st[0].angles == (0.0, 90 * DEG, 0.0) and st[0].label == "a"
    assert isinstance(st[1], Dwell) and st[1].duration == 12.0
    assert isinstance(st[2], Rotate) and st[2].rate == -10 * DEG and st[2].turns == 2 and st[2].axis == "outer"
    assert st[2].label == "rotate3"
    assert isinstance(st[3], Rate) and st[3].axis == 2 and st[3].rate == 30 * DEG and st[3].duration == 4.0
    # tumble -> index + dwell pairs pos01, pos02; repeat -> suffixes -c1, -c2, numbering continues
    assert [(x.kind, x.label) for x in st[4:]] == [
        ("index", "pos01"), ("dwell", "pos01"), ("index", "pos02"), ("dwell", "pos02"),
        ("index", "pos03-c1"), ("dwell", "pos03-c1"), ("index", "pos04-c2"), ("dwell", "pos04-c2")]
    assert s.labels[:4] == ["move-a", "a", "rotate3", "rate4"]
    assert "move-pos01" in s.labels and "pos04-c2" in s.labels
    assert st[6].origin == "5"


def test_default_settle_tolerance_is_two_counts():
    s = loads_schedule('[[steps]]\nkind = "dwell"\nduration = 1\n')
    assert s.settings.settle_tol == 2 * 2 * math.pi / COUNTS_PER_REV


def test_overrides():
    s = loads_schedule(GOOD, "demo.toml", overrides={"dwell": 3.0, "turns": 5})
    assert s.steps[1].duration == 3.0 and s.steps[2].turns == 5
    with pytest.raises(ScheduleError, match=r"demo.toml: override nope = 1: the schedule has no parameter 'nope'"):
        loads_schedule(GOOD, "demo.toml", overrides={"nope": 1})
    with pytest.raises(ScheduleError, match=r"override turns = 1.5: expected a int"):
        loads_schedule(GOOD, "demo.toml", overrides={"turns": 1.5})


@pytest.mark.parametrize("name", available_schedules())
def test_ready_made_schedules_load(name):
    s = load_schedule(name)
    assert s.steps and s.labels
    assert s.n_angles() == 3
    assert len(set(s.labels)) == len(s.labels)
    # the dwell is a parameter a scenario / the CLI can override
    assert "dwell" in s.parameters
    short = load_schedule(name, {"dwell": 1.0})
    assert any(x.duration == 1.0 for x in short.steps if isinstance(x, Dwell))


def test_ready_made_names():
    assert {"six_position", "twelve_position", "eighteen_position", "twentyfour_position", "rotations",
            "seed_000", "seed_001", "seed_003"} <= set(available_schedules())
    assert load_schedule("six-position").name == "six-position"
    six = load_schedule("six_position")
    assert len([x for x in six.steps if isinstance(x, Index)]) == 6
    assert len([x for x in load_schedule("twentyfour_position").steps if isinstance(x, Index)]) == 24
    assert len([x for x in load_schedule("eighteen_position").steps if isinstance(x, Index)]) == 18


def test_twentyfour_positions_are_the_24_axis_aligned_orientations():
    import numpy as np

    def rz(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    def rx(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])

    mats = set()
    for x in load_schedule("twentyfour_position").steps:
        if isinstance(x, Index):
            o, m, i = x.angles
            C = rz(o) @ rx(m) @ rz(i)
            assert np.allclose(C, np.round(C), atol=1e-12)
            mats.add(tuple(np.round(C).astype(int).ravel()))
    assert len(mats) == 24


BAD = [
    ("[[steps]]\nkind = \"spin\"\n", r"x.toml: step 1: key 'kind' = 'spin': expected one of index, dwell"),
    ("[[steps]]\nkind = \"dwell\"\n", r"x.toml: step 1 \(dwell\): missing key 'duration'"),
    ("[[steps]]\nkind = \"dwell\"\nduration = -1\n", r"step 1 \(dwell\): key 'duration' = -1: expected a positive"),
    ("[[steps]]\nkind = \"dwell\"\nduration = \"$d\"\n", r"step 1 \(dwell\): key 'duration' = '\$d': no parameter 'd'"),
    ("[[steps]]\nkind = \"dwell\"\nduration = 1\nspeed = 2\n", r"step 1 \(dwell\): unknown key\(s\) \['speed'\]"),
    ("[[steps]]\nkind = \"index\"\nangles_deg = [0, 1, 2, 3]\n",
     r"step 1 \(index\): key 'angles_deg' = \[0, 1, 2, 3\]: expected a list of 1 to 3 angles"),
    ("[[steps]]\nkind = \"index\"\nangles_deg = [0, \"a\"]\n", r"step 1 \(index\): key 'angles_deg'"),
    ("[[steps]]\nkind = \"index\"\nangles_deg = [0, 0]\nabsolute = 1\n", r"key 'absolute' = 1: expected true or false"),
    ("[[steps]]\nkind = \"rotate\"\naxis = \"outer\"\nrate_dps = 0\nturns = 1\n",
     r"step 1 \(rotate\): key 'rate_dps' = 0: expected a nonzero signed rate"),
    ("[[steps]]\nkind = \"rotate\"\naxis = \"outer\"\nrate_dps = 10\nturns = 1.5\n",
     r"step 1 \(rotate\): key 'turns' = 1.5: expected a whole number of turns"),
    ("[[steps]]\nkind = \"rotate\"\naxis = 7\nrate_dps = 10\nturns = 1\n", r"key 'axis' = 7: expected an axis name"),
    ("[[steps]]\nkind = \"rate\"\naxis = \"inner\"\nrate_dps = 10\n", r"step 1 \(rate\): missing key 'duration'"),
    ("[[steps]]\nkind = \"tumble\"\nattitudes_deg = []\ndwell = 1\n", r"step 1 \(tumble\): key 'attitudes_deg' = \[\]"),
    ("[[steps]]\nkind = \"tumble\"\nattitudes_deg = [[0, 0], [0, 0, 0]]\ndwell = 1\n",
     r"step 1 \(tumble\): key 'attitudes_deg', entry 2 has 3 angles, entry 1 has 2"),
    ("[[steps]]\nkind = \"tumble\"\nattitudes_deg = [[0, 0]]\n", r"step 1 \(tumble\): missing key 'dwell'"),
    ("[[steps]]\nkind = \"repeat\"\ntimes = 0\n", r"step 1 \(repeat\): key 'times' = 0: expected a whole number"),
    ("[[steps]]\nkind = \"repeat\"\ntimes = 2\n", r"step 1 \(repeat\): missing key 'steps'"),
    ("[[steps]]\nkind = \"repeat\"\ntimes = 2\n[[steps.steps]]\nkind = \"dwell\"\n",
     r"x.toml: step 1.1 \(dwell\): missing key 'duration'"),
    ("[[steps]]\nkind = \"dwell\"\nduration = 1\n[[steps]]\nkind = \"dwell\"\nduration = 1\nlabel = \" a\"\n",
     r"step 2 \(dwell\): key 'label' = ' a': expected a non-empty text"),
    ("[[steps]]\nkind = \"index\"\nangles_deg = [0, 0]\n[[steps]]\nkind = \"index\"\nangles_deg = [0, 0, 0]\n",
     r"step 2 \(index\): 3 angles where earlier steps have 2"),
    ("[schedule]\nname = \"x\"\n", r"x.toml: no \[\[steps\]\]"),
    ("[steps]\nkind = 1\n", r"x.toml: \[\[steps\]\]: expected a non-empty list"),
    ("[settings]\nsettle_hold = 0\n[[steps]]\nkind = \"dwell\"\nduration = 1\n",
     r"\[settings\]: settle_hold = 0: expected a positive number"),
    ("[settings]\nhold = 1\n[[steps]]\nkind = \"dwell\"\nduration = 1\n", r"\[settings\]: unknown key 'hold'"),
    ("[parameters]\ndwell = \"long\"\n[[steps]]\nkind = \"dwell\"\nduration = 1\n",
     r"\[parameters\]: dwell = 'long': expected a number"),
    ("[extra]\n[[steps]]\nkind = \"dwell\"\nduration = 1\n", r"x.toml: unknown section\(s\) \['extra'\]"),
    ("[schedule]\nnam = 1\n[[steps]]\nkind = \"dwell\"\nduration = 1\n", r"\[schedule\]: unknown key\(s\) \['nam'\]"),
    ("[[steps]]\nkind = \"dwell\"\nduration = \n", r"x.toml: not valid TOML"),
]


@pytest.mark.parametrize("text,message", BAD)
def test_errors(text, message):
    with pytest.raises(ScheduleError, match=message):
        loads_schedule(text, "x.toml")


def test_missing_file_and_unknown_name(tmp_path):
    with pytest.raises(ScheduleError, match=r"schedule file .*nope.toml does not exist"):
        load_schedule(tmp_path / "nope.toml")
    with pytest.raises(ScheduleError, match=r"schedule 'sevenposition': no ready-made schedule.*six_position"):
        load_schedule("sevenposition")
    p = tmp_path / "s.toml"
    p.write_text('[[steps]]\nkind = "dwell"\nduration = 2\n')
    assert load_schedule(p).steps[0].duration == 2.0
