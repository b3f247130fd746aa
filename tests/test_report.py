"""The HTML report in a real headless browser (Chromium): the page loads from a file with no
server, its plots are in the rendered DOM, and the browser logs no console message. A page with
a script error is the control that shows the console check can fail."""
import json
import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
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


@pytest.fixture(scope="module")
def before_after(tmp_path_factory, conformance):
    """`calbench report`'s page for the spec's example: a result made by `add` (biases only ->
    + scale factors and misalignments, the example's true model), so the page has a before and
    an after."""
    from components.diagnosis.compare import compare
    from components.diagnosis.ladder import ladder_entry
    from components.diagnosis.report_run import write_model_report
    from components.model.result import result_from_fit

    out = tmp_path_factory.mktemp("before_after")
    log = read_log(conformance / "example")
    data = LogData.from_log(log)
    first = ["gyro.bias", "acc.bias"]
    before = result_from_fit(calibrate(data, first), first, data, log)
    full = list(DEFAULT_EFFECTS)
    after = result_from_fit(calibrate(data, full), full, data, log)
    after.extra["ladder"] = [ladder_entry(compare(data, before, fitted_parameters=len(before.values)), first, "biases"),
                             ladder_entry(compare(data, after, fitted_parameters=len(after.values)), full,
                                          "+ sf, mis")]
    html_path, json_path = write_model_report(out / "page.html", log, data, after, title="example before/after")
    return html_path, json_path


def _legend(svg_dom: str, gid: str):
    """(tick label -> y, y span of the colour bar, PNG rows from the displayed top) of a heat map's
    colour bar, read from the rendered DOM."""
    import base64
    import io

    from PIL import Image

    start = svg_dom.index(f'id="{gid}"')
    end = svg_dom.index("</g>\n  </g>", start) if "</g>\n  </g>" in svg_dom[start:] else len(svg_dom)
    seg = svg_dom[start:end]
    img = re.search(r'<image[^>]*href="data:image/png;base64,([^"]+)"[^>]*>', seg)
    assert img, "the colour bar is an inline image"
    tag = img.group(0)
    png = Image.open(io.BytesIO(base64.b64decode(img.group(1)))).convert("RGB")
    rows = [png.getpixel((png.size[0] // 2, r)) for r in range(png.size[1])]
    if "scale(1 -1)" in tag or "scale(1, -1)" in tag:  # drawn flipped: the PNG's last row is on top
        rows = rows[::-1]
    ticks = {m.group(2): float(m.group(1)) for m in re.finditer(r'<text[^>]*\by="([-\d.]+)"[^>]*>([\d.]+)</text>', seg)}
    ys = [float(v) for v in re.findall(r'<use[^>]*\by="([-\d.]+)"', seg)]
    return ticks, (min(ys), max(ys)), rows


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (.ci/run installs it)")
def test_before_after_page_names_its_models_and_centres_the_heat_map_on_noise(before_after, tmp_path):
    html_path, json_path = before_after
    dom, console = render(html_path, tmp_path)
    assert console == [], console
    headings = [re.sub(r"<[^>]+>", "", h) for h in re.findall(r"<h2[^>]*>(.*?)</h2>", dom)]
    names = ("biases", "+ sf, mis")
    for h in headings:
        if not h.startswith(("Ladder", "Provenance")):
            assert any(n in h for n in names), f"section {h!r} does not say which model it shows"
    assert any(h.startswith("Where biases fails (before)") for h in headings), headings
    assert any(h.startswith("Where + sf, mis fails (after)") for h in headings), headings
    assert any(h.startswith("Diagnosis of + sf, mis") for h in headings), headings
    assert any(h.startswith("Noise") and "+ sf, mis" in h for h in headings), headings
    # the after-model is the example's true model: nothing misfits beyond noise; the before-model
    # lacks scale factors and misalignments: flagged (independent of the page: the twin's cells)
    twin = json.loads(json_path.read_text())
    after, before = twin["views"][1]["comparison"]["misfits"], twin["views"][0]["comparison"]["misfits"]
    assert not any(after["flagged"].values()) and before["flagged"]["segment"]
    assert "no segment × channel misfits beyond noise" in dom
    for k in (0, 1):
        ticks, (top, bottom), rows = _legend(dom, f"misfit-map-{k}-legend")
        assert "1" in ticks
        # the legend's 1 sits in the middle of the bar, values above it higher up
        assert abs(ticks["1"] - (top + bottom) / 2) < 0.01 * (bottom - top) + 4, (ticks, top, bottom)
        assert all(ticks[t] < ticks["1"] for t in ticks if float(t) > 1)
        r, g, b = rows[len(rows) // 2]
        assert min(r, g, b) > 225, f"the colour at 1 (noise) is {rows[len(rows) // 2]}, not white"
        assert rows[0][0] > rows[0][2] + 60, f"the top (above noise) is {rows[0]}, not red"
        assert rows[-1][2] > rows[-1][0] + 60, f"the bottom (below noise) is {rows[-1]}, not blue"


def test_report_command_and_a_bad_truth_file(conformance, tmp_path, capsys):
    from components.cli import main

    model = tmp_path / "m.json"
    assert main(["calibrate", str(conformance / "example"), "--out", str(model)]) == 0
    page = tmp_path / "page.html"
    assert main(["report", str(conformance / "example"), "--model", str(model), "--out", str(page),
                 "--diagnose", "none", "--no-noise"]) == 0
    text = page.read_text()
    assert "Where gyro.bias+gyro.sf+gyro.mis+acc.bias+acc.sf+acc.mis fails" in text
    assert "no segment × channel misfits beyond noise" in text
    bad = tmp_path / "truth.json"
    bad.write_text(json.dumps({"seed": 1}))
    capsys.readouterr()
    assert main(["report", str(conformance / "example"), "--model", str(model), "--out", str(page),
                 "--truth", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and '"effects"' in err[0], err
    # a truth of another run (other segments, another length) is refused: its errors would read
    # as hundreds of σ; the log's own segments, or its length, are accepted
    from components.logs.logfile import read_log

    log = read_log(conformance / "example")
    lab = [str(x) for i, x in enumerate(log.segment) if i == 0 or x != log.segment[i - 1]]
    length = float(log.time[-1] - log.time[0] + log.dt)
    for segments, stopped, code in (([{"label": "az000"}, {"label": "az090"}], 2 * length, 2),
                                    ([{"label": x} for x in lab], 2 * length, 0),
                                    ([{"label": "az000"}], length, 0)):
        other = tmp_path / "other.truth.json"
        other.write_text(json.dumps({"scenario": {"name": "seed000"}, "effects": {}, "segments": segments,
                                     "run": {"stopped_at_s": stopped}}))
        capsys.readouterr()
        assert main(["report", str(conformance / "example"), "--model", str(model), "--out", str(page),
                     "--diagnose", "none", "--no-noise", "--truth", str(other)]) == code
        if code:
            assert "the truth of scenario 'seed000', whose segments and length are not those" in capsys.readouterr().err


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
    # and as numbers for scripts: the truth in SI (40 ug/g2 = 40e-6 / 9.80665 s2/m) and the error in σ
    k2 = twin["truth_values"][0]
    assert k2["parameter"] == "acc.k2.z" and k2["truth"] == pytest.approx(40e-6 / 9.80665)
    assert k2["error_sigmas"] == pytest.approx((k2["value"] - k2["truth"]) / k2["sigma"]) and abs(k2["error_sigmas"]) < 3


def test_a_long_logs_residual_plot_stays_a_page_not_a_megabyte_per_thousand_points():
    """An 8-hour log has ~30 000 blocks a channel: drawn as one vector element each, the
    residual plot alone was 19 MB of SVG. Above report_plots.DENSE_POINTS a channel's points are
    one embedded image, so the plot's size no longer grows with the log; below, they stay
    vector marks (one per point)."""
    from types import SimpleNamespace

    from components.diagnosis.report_plots import DENSE_POINTS, residual_vs_time

    def plot(blocks):
        rng = np.random.default_rng(1)
        n = blocks * 10
        rows = {"channel": np.repeat(np.arange(6), blocks), "start": np.tile(np.arange(blocks) * 10, 6),
                "stop": np.tile(np.arange(blocks) * 10 + 10, 6), "z": rng.standard_normal(6 * blocks)}
        return residual_vs_time(SimpleNamespace(rows=rows, time=np.arange(n) * 0.01, segment=None), "m")

    few, many, more = plot(DENSE_POINTS // 4), plot(15_000), plot(30_000)
    assert few.count("<use") >= 6 * (DENSE_POINTS // 4) and "<image" not in few
    assert many.count("<image") == 6 and many.count("<use") < 100
    assert len(more) < 1.25 * len(many) and len(more) < 2_000_000, (len(many), len(more))


def test_report_truth_in_the_frame_the_result_estimates_in(conformance, tmp_path, capsys):
    """A result with the accelerometers' lower-triangular misalignments only (a system-level or
    positions result: the accelerometer-defined frame) is judged against the truth turned into
    that frame (docs: components.navigation.truth_frame): an injected acc.mis.xy of 20″ becomes a
    gyro.mis.yx of +20″ and an acc.mis.yx of +20″, and is not listed as 'not in the model'."""
    from components.cli import main

    model = tmp_path / "m.json"
    assert main(["calibrate", str(conformance / "example"), "--out", str(model)]) == 0
    doc = json.loads(model.read_text())
    for p in ("acc.mis.xy", "acc.mis.xz", "acc.mis.yz"):
        doc["parameters"].pop(p, None)
    model.write_text(json.dumps(doc))
    arcsec = math.pi / 180 / 3600
    (tmp_path / "t.truth.json").write_text(json.dumps({"effects": {"acc.mis.xy": 20 * arcsec}}))
    capsys.readouterr()
    assert main(["report", str(conformance / "example"), "--model", str(model), "--out", str(tmp_path / "p.html"),
                 "--diagnose", "none", "--no-noise", "--truth", str(tmp_path / "t.truth.json")]) == 0
    assert "accelerometer-defined frame" in capsys.readouterr().out
    lines = json.loads((tmp_path / "p.json").read_text())["truth"]
    assert any(x.startswith("gyro.mis.yx: truth +20 arcsec") for x in lines), lines
    assert any(x.startswith("acc.mis.yx: truth +20 arcsec") for x in lines), lines
    assert not any(x.startswith("acc.mis.xy") for x in lines), lines


@pytest.mark.parametrize("given, page", [("my.page.v2.html", "my.page.v2"), ("rep.mem", "rep.mem"), ("plain", "plain")])
def test_report_writes_the_page_it_was_given(conformance, tmp_path, given, page):
    """--out names the page: a dotted name keeps its parts (my.page.v2.html was written as
    my.page.html, so rep.mem.html and rep.sp.html overwrote one another); the JSON twin beside it."""
    from components.cli import main

    model = tmp_path / "m.json"
    assert main(["calibrate", str(conformance / "example"), "--out", str(model)]) == 0
    assert main(["report", str(conformance / "example"), "--model", str(model), "--out", str(tmp_path / given),
                 "--diagnose", "none", "--no-noise"]) == 0
    written = sorted(p.name for p in tmp_path.iterdir() if p.suffix in (".html", ".json") and p.name != "m.json")
    assert written == [f"{page}.html", f"{page}.json"]
    assert json.loads((tmp_path / f"{page}.json").read_text())["comparison"]


def test_block_residuals_file_gives_each_blocks_first_and_last_time(tmp_path):
    """compare --block-residuals: a row per block and channel whose t_start and t_stop are the
    times of the block's first and last samples, the same from a spilled time column (read a
    piece at a time) as from one in memory."""
    from types import SimpleNamespace

    from components.diagnosis.residual_export import write_block_residuals
    from components.logs import spill
    from components.logs.labels import SegmentLabels

    rng = np.random.default_rng(9)
    n, blocks = 50_000, 400
    time = 3.0 + np.cumsum(rng.uniform(0.9e-3, 1.1e-3, n))
    start = np.sort(rng.choice(n - 10, blocks, replace=False))
    stop = np.minimum(start + rng.integers(1, 200, blocks), n + 5)  # (a stop past the end: the last sample)
    rows = {"channel": rng.integers(0, 6, blocks), "start": start, "stop": stop, "moving": rng.random(blocks) < 0.3,
            "z": rng.standard_normal(blocks)}
    seg = SegmentLabels(np.array([0, n // 2]), np.array([0, 1]), ["a", "b"], n)
    on_disk = spill.spilled_array((n,))
    on_disk[:] = time
    files = []
    for t in (time, on_disk):
        path = tmp_path / f"blocks{len(files)}.csv"
        write_block_residuals(str(path), SimpleNamespace(rows=rows, time=t, segment=seg, misfits=None))
        files.append(path.read_text())
    assert files[0] == files[1]
    lines = files[0].splitlines()
    assert lines[0].startswith("t_start,t_stop,segment,channel")
    got = np.array([[float(x) for x in line.split(",")[:2]] for line in lines[1:]])
    order = np.lexsort((rows["channel"], rows["start"]))
    assert np.array_equal(got[:, 0], time[start[order]])
    assert np.array_equal(got[:, 1], time[np.minimum(stop[order], n) - 1])
