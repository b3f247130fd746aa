"""A schedule that asks the table for a rate beyond its limit is refused, naming the step and the
limit: the built-in table turned at its 300 deg/s under the label of the 1000 deg/s asked for,
and plan's bound and the log described a motion nobody designed. And a schedule's .toml is a
schedule even when a log of the same stem lies beside it."""
from __future__ import annotations

from components.cli import main

SCHEDULE = """
[schedule]
name = "too-fast"
[[steps]]
kind = "index"
angles_deg = [0, 0, 0]
label = "z-up"
[[steps]]
kind = "rotate"
axis = "outer"
rate_dps = {rate}
turns = 2
label = "spin"
"""


def test_a_rate_beyond_the_tables_limit_is_refused(tmp_path, capsys):
    fast = tmp_path / "fast.toml"
    fast.write_text(SCHEDULE.format(rate=1000.0))
    (tmp_path / "fast.json").write_text("{}")   # a log's pair of the same stem
    (tmp_path / "fast.csv").write_text("")
    capsys.readouterr()
    assert main(["plan", str(fast)]) == 2
    err = capsys.readouterr().err
    assert "step 2 (rotate): rate 1000 deg/s, beyond the table's outer axis limit of 300 deg/s" in err, err
    ok = tmp_path / "ok.toml"
    ok.write_text(SCHEDULE.format(rate=200.0))
    assert main(["plan", str(ok)]) == 0
