"""The HTML report in a real headless browser (Chromium): the page loads from a file with no
server, its plots are in the rendered DOM, and the browser logs no console message. A page with
a script error is the control that shows the console check can fail."""
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-logging=stderr", "--v=0", "--dump-dom"]


def render(page: Path, tmp: Path) -> tuple[str, list[str]]:
    """DOM after load and the console lines Chromium logged."""
    proc = subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={tmp / 'profile'}", page.as_uri()],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    console = [ln for ln in proc.stderr.splitlines() if ":CONSOLE" in ln]
    return proc.stdout, console


@pytest.fixture(scope="module")
def report(tmp_path_factory, conformance):
    from components.diagnosis.compare import compare
    from components.diagnosis.diagnose import diagnose
    from components.diagnosis.report import build_report
    from components.model.result import result_from_fit

    out = tmp_path_factory.mktemp("report")
    log = read_log(conformance / "example")
    data = LogData.from_log(log)
    fit = calibrate(data, list(DEFAULT_EFFECTS))
    model = result_from_fit(fit, list(DEFAULT_EFFECTS), data, log)
    comp = compare(data, model, fitted_parameters=len(model.values))
    diag = diagnose(data, model, forward=False)
    ladder = [{"model": "baseline", "effects": list(DEFAULT_EFFECTS), "chi2_per_dof": comp.chi2_per_dof,
               "rms": {k: v["rms"] for k, v in comp.channels.items()},
               "noise_floor": {k: v["noise_floor"] for k, v in comp.channels.items()}}]
    return build_report(out / "report", title="example", comparison=comp, diagnosis=diag,
                        ladder=ladder, provenance={"log": str(conformance / "example")})


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (.ci/run installs it)")
def test_report_renders_in_headless_chromium(report, tmp_path):
    html_path, json_path = report
    dom, console = render(html_path, tmp_path)
    assert console == [], console
    # the ladder, segment map, residual-vs-time, conditions and three signature plots
    assert len(re.findall(r"<svg", dom)) >= 6
    assert "Diagnosis" in dom and "Ladder" in dom and "Provenance" in dom
    assert "no significant effect is missing" in dom  # the shared example's model is complete
    twin = json.loads(json_path.read_text())
    assert twin["diagnosis"]["verdict"] is None
    assert set(twin["comparison"]["channels"]) == {"gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"}


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (.ci/run installs it)")
def test_console_check_catches_a_script_error(tmp_path):
    bad = tmp_path / "bad.html"
    bad.write_text("<!DOCTYPE html><html><body><script>undefinedFunction();</script></body></html>")
    _, console = render(bad, tmp_path)
    assert any("undefinedFunction" in ln for ln in console)


def test_report_is_self_contained(report):
    html = report[0].read_text()
    # nothing fetched at view time: no external script, stylesheet or image
    assert not re.search(r"<(script|link|img)\b", html)
    # nothing points outside the page (XML namespace names are identifiers, not fetched)
    assert not re.search(r'(src|href)="(https?:)?//', html)


def test_demo_page_shows_before_after_and_the_truth(tmp_path, capsys):
    """The demo writes the same page: the baseline's heat map and diagnosis under the baseline's
    name, the corrected model's under its own, the hidden effect against its truth; the corrected
    model flags nothing, the baseline does (the JSON twin's cells, not the page's words)."""
    from components.cli.demo import run_demo

    assert run_demo(tmp_path / "demo", dwell=2.0) == 0
    html_text = (tmp_path / "demo" / "report.html").read_text()
    twin = json.loads((tmp_path / "demo" / "report.json").read_text())
    names = [v["model"] for v in twin["views"]]
    assert names == ["baseline", "+ acc.k2"], names
    for name, role in zip(names, ("before", "after")):
        assert f"Where {name} fails ({role})" in html_text
        assert f"Diagnosis of {name}" in html_text
    before, after = (v["comparison"]["misfits"]["flagged"] for v in twin["views"])
    assert any(c["channel"] == "acc_z" for c in before["segment"]), before["segment"]
    assert not any(after.values()), after
    assert twin["views"][0]["diagnosis"]["verdict"] == "acc.k2"
    assert twin["views"][1]["diagnosis"]["verdict"] is None
    assert "Recovered against the truth: + acc.k2" in html_text
    assert twin["truth"] and twin["truth"][0].startswith("acc.k2.z: truth +40 ug/g2, recovered")
