"""Test campaigns (components.campaign) on real Dask local clusters and real FMUs.

One campaign of 22 cases: the six-position schedule (1 s dwell, 100 Hz) calibrated by least
squares on our IMU FMU (10 Monte-Carlo seeds) and on a mapped supplier IMU (10), plus one case
on a supplier IMU that segfaults and one on a supplier IMU that hangs.

- 2 workers, uninterrupted: the 20 good cases pass, the segfault and the hang are errored with
  their reason, the reports say so (JUnit, summary, HTML) and the [expected] block holds.
- 1 worker, terminated after a few case records exist, then resumed: the final records are
  byte-identical to the 2-worker run (so: worker count and completion order do not matter, and
  resume loses nothing), and no case that had finished before the kill ran again."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from components.campaign.criteria import evaluate
from components.campaign.reader import load_campaign
from components.campaign.store import Store
from components.cli import main as cli_main
from components.errors import CampaignError

ROOT = Path(__file__).resolve().parents[1]
FMUS = Path(__file__).parent / "fmus"
AX = "XYZ"
MAPPING = "\n".join([f'"omega.{c.lower()}" = "AngularRate_{c}"' for c in AX]
                    + [f'"f.{c.lower()}" = "Accel_{c}"' for c in AX]
                    + [f'"gyro.{c.lower()}" = "GyroRate_{c}"' for c in AX]
                    + [f'"acc.{c.lower()}" = "Accel_Out_{c}"' for c in AX])
EFFECTS = "\n".join([f'"gyro.bias.{c.lower()}" = ["GyroBias_{c}", "deg/s"]' for c in AX]
                    + [f'"acc.bias.{c.lower()}" = ["AccBias_{c}", "g"]' for c in AX]
                    + [f'"acc.sf.{c.lower()}" = ["AccSF_{c}", "1"]' for c in AX])
N_CASES = 22


def _supplier(name: str, model: str, extra: str = "") -> str:
    return f"""
[systems.{name}]
imu = "build:{FMUS / model}"
gyro_output = "rate"
acc_output = "specific_force"
{extra}
[systems.{name}.mapping]
{MAPPING}
[systems.{name}.effect_map]
{EFFECTS}
"""


CAMPAIGN = f"""
[campaign]
name = "test"
description = "22 cases: our IMU and a supplier's, 10 seeds each; a segfaulting and a hanging supplier"
seed = 7
replicates = 10
timeout_s = 60

[scenario]
file = "{ROOT / 'examples' / 'scenarios' / 'six_position.toml'}"
step = 0.01
[scenario.schedule_overrides]
dwell = 1.0

[systems.ours]
imu = "builtin:imu"
{_supplier("acme", "supplier_imu")}
{_supplier("segv", "supplier_imu", 'replicates = 1')}
[systems.segv.parameters]
SegfaultAt = 3.0
{_supplier("hang", "supplier_imu", 'replicates = 1' + chr(10) + 'timeout_s = 6')}
[systems.hang.parameters]
HangAt = 3.0

[procedures.lsq]
method = "lsq"

[variations."acc.bias.x"]
distribution = "uniform"
low = "-200 ug"
high = "200 ug"
[variations."gyro.bias.z"]
distribution = "normal"
mean = "0 deg/h"
sigma = "0.01 deg/h"

[[criteria]]
id = "ACC-BIAS"
requirement = "REQ-010"
kind = "estimate"
parameters = ["acc.bias.*"]
tolerance = "40 ug"

[[criteria]]
id = "GYRO-BIAS"
requirement = "REQ-011"
kind = "estimate"
parameters = ["gyro.bias.*"]
crb_sigmas = 5
systems = ["ours"]

[[criteria]]
id = "OBS"
requirement = "REQ-020"
kind = "crb"
parameters = ["acc.sf.*"]
max = "5 ppm"
systems = ["ours"]

[[criteria]]
id = "FIT"
requirement = "REQ-030"
kind = "chi2"
max = 1.6
systems = ["ours"]

[expected]
verdict = "pass"
[[expected.cases]]
system = "segv"
verdict = "error"
reason = "SIGSEGV"
[[expected.cases]]
system = "hang"
verdict = "error"
reason = "timeout"
"""


@pytest.fixture(scope="module")
def campaign_file(tmp_path_factory) -> Path:
    p = tmp_path_factory.mktemp("campaign") / "test.toml"
    p.write_text(CAMPAIGN)
    load_campaign(p)  # builds the supplier FMUs once, before any worker needs them
    return p


@pytest.fixture(scope="module")
def two_workers(campaign_file, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("two")
    rc = cli_main(["campaign", str(campaign_file), "--out", str(out), "--workers", "2", "--pages", "1"])
    assert rc == 0  # complete and as the [expected] block says
    return out


def test_cases_expand_deterministically(campaign_file):
    a, b = load_campaign(campaign_file), load_campaign(campaign_file)
    assert len(a.cases) == N_CASES
    assert [c.key() for c in a.cases] == [c.key() for c in b.cases]
    ours = [c for c in a.cases if c.system == "ours"]
    acme = [c for c in a.cases if c.system == "acme"]
    # paired: a replicate has the same seed and draws whatever the system
    assert [(c.seed, c.variation) for c in ours] == [(c.seed, c.variation) for c in acme]
    assert len({c.seed for c in ours}) == 10


def test_two_workers_verdicts_and_reports(two_workers):
    store = Store(two_workers)
    recs = {r["id"]: r for r in store.records(store.done())}
    assert len(recs) == N_CASES
    for cid, r in recs.items():
        if cid.startswith("lsq-segv"):
            assert r["verdict"] == "error" and "SIGSEGV" in r["reason"], r["reason"]
        elif cid.startswith("lsq-hang"):
            assert r["verdict"] == "error" and "timeout" in r["reason"], r["reason"]
        else:
            assert r["verdict"] == "pass", (cid, r["reason"], r["criteria"])
            assert all(c["passed"] for c in r["criteria"])
    ours = recs["lsq-ours-g0-r0"]
    assert {c["id"] for c in ours["criteria"]} == {"ACC-BIAS", "GYRO-BIAS", "OBS", "FIT"}
    assert {c["requirement"] for c in ours["criteria"]} == {"REQ-010", "REQ-011", "REQ-020", "REQ-030"}
    assert {c["id"] for c in recs["lsq-acme-g0-r0"]["criteria"]} == {"ACC-BIAS"}
    # the supplier's truth is what reached its parameters (no misalignment parameter: not injected)
    assert "acc.bias.x" in recs["lsq-acme-g0-r0"]["truth"]
    lost = recs["lsq-acme-g0-r0"]["not_injected"]
    assert "acc.mis.xy" in lost["effects"] and lost["seed"] is True
    # no time inside a case record
    assert not any("time" in k or k in ("start", "end") for k in ours)

    junit = ET.parse(two_workers / "junit.xml").getroot()
    assert (junit.get("tests"), junit.get("failures"), junit.get("errors")) == (str(N_CASES), "0", "2")
    errs = {tc.get("name"): tc.find("error").get("message") for tc in junit.iter("testcase")
            if tc.find("error") is not None}
    assert set(errs) == {"lsq-segv-g0-r0", "lsq-hang-g0-r0"}

    summary = json.loads((two_workers / "summary.json").read_text())
    assert summary["counts"] == {"pass": 20, "fail": 0, "error": 2, "missing": 0, "total": N_CASES}
    assert summary["expected"] == {"ok": True, "mismatches": []}
    reqs = {r["requirement"]: r for r in summary["requirements"]}
    assert reqs["REQ-011"]["verdict"] == "pass"
    assert reqs["REQ-010"]["verdict"] == "error"  # ACC-BIAS applies to the crashed suppliers too

    manifest = json.loads((two_workers / "manifest.json").read_text())
    for k in ("campaign", "scenario", "schedule", "fmu:turntable", "fmu:ours", "fmu:acme", "fmu:segv", "fmu:hang"):
        assert len(manifest["files"][k]["sha256"]) == 64
    assert manifest["software"]["libraries"]["distributed"]
    assert manifest["seeds"]["cases"]["lsq-ours-g0-r0"] == ours["seed"]
    assert manifest["sessions"][0]["start"] and manifest["sessions"][0]["end"]

    page = (two_workers / "report.html").read_text()
    for text in ("Traceability", "REQ-030", "Cramér–Rao", "SIGSEGV", "timeout", "Manifest", "<svg"):
        assert text in page
    pages = list((two_workers / "pages").glob("*.html"))
    assert len(pages) == 1 and f"href='pages/{pages[0].name}'" in page


def test_kill_resume_one_worker_identical(campaign_file, two_workers, tmp_path):
    """1 worker, SIGTERM after a few records, --resume: byte-identical to the 2-worker run, and
    no case that had finished before the kill ran again. The case running at the kill leaves no
    temporary files (found: its directory, with its two unpacked FMUs, left by a SIGTERM on a
    loaded machine, where the worker dies before the case can clean up)."""
    out = tmp_path / "one"
    temp = tmp_path / "temp"
    temp.mkdir()
    cmd = [sys.executable, "-m", "components.cli", "campaign", str(campaign_file), "--out", str(out),
           "--workers", "1", "--pages", "0"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            env={**os.environ, "TMPDIR": str(temp)})
    cases = out / "cases"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if cases.is_dir() and len(list(cases.glob("*.json"))) >= 4:
            break
        time.sleep(0.2)
    assert proc.poll() is None, proc.stdout.read().decode()
    proc.send_signal(signal.SIGTERM)
    log = proc.communicate(timeout=60)[0].decode()
    assert proc.returncode == 130, log
    before = {p.stem for p in cases.glob("*.json")}
    assert 4 <= len(before) < N_CASES
    assert not list(cases.glob("*.tmp")) and not list(cases.glob(".*"))
    assert [p.name for p in temp.iterdir() if p.name.startswith("calbench")] == []

    # without --resume the folder is refused
    assert cli_main(["campaign", str(campaign_file), "--out", str(out), "--workers", "1"]) == 2
    assert cli_main(["campaign", str(campaign_file), "--out", str(out), "--workers", "1", "--resume",
                     "--pages", "0"]) == 0

    ref = {p.name: p.read_bytes() for p in (two_workers / "cases").glob("*.json")}
    got = {p.name: p.read_bytes() for p in cases.glob("*.json")}
    assert sorted(got) == sorted(ref)
    assert [n for n in ref if got[n] != ref[n]] == []
    runs = Store(out).runs()
    assert all(runs.get(cid) == 1 for cid in before), {cid: runs.get(cid) for cid in before}
    assert set(runs) == {n[:-5] for n in ref}
    manifest = json.loads((out / "manifest.json").read_text())
    s1, s2 = manifest["sessions"]
    assert s1["interrupted"] and not s2["interrupted"] and s2["resume"]
    assert set(s2["ran"]).isdisjoint(before) and len(s2["ran"]) == N_CASES - len(before)
    # the summary of the resumed campaign equals the uninterrupted one
    assert (out / "summary.json").read_bytes() == (two_workers / "summary.json").read_bytes()
    assert (out / "junit.xml").read_bytes() == (two_workers / "junit.xml").read_bytes()


# ----------------------------------------------------------------------------- no cluster
def _write(tmp_path, text: str) -> Path:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("where", ["fsync", "replace"])
def test_a_record_interrupted_while_written_leaves_no_file(tmp_path, monkeypatch, where):
    """SIGTERM becomes an exception wherever it lands in the main thread; landing between a
    record's write and its rename (the fsync waits on the disk: the kill-and-resume test once left
    a .tmp there), it leaves the old record as it was and no temporary file."""
    from components.campaign import store as store_module

    store = Store(tmp_path)
    store.prepare()
    store.write_case({"id": "kept"}, '{"old": 1}')

    def interrupted(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(store_module.os, where, interrupted)
    for case in ("kept", "new"):
        with pytest.raises(KeyboardInterrupt):
            store.write_case({"id": case}, '{"new": 2}')
    monkeypatch.undo()
    assert sorted(p.name for p in store.cases_dir.iterdir()) == ["kept.json"]
    assert store.case_path("kept").read_text() == '{"old": 1}'
    assert store.done() == {"kept"}


@pytest.mark.parametrize("change, words", [
    (("requirement = \"REQ-010\"\n", ""), ["[[criteria]] ACC-BIAS requirement", "requirement it verifies"]),
    (('kind = "chi2"', 'kind = "chi3"'), ["kind", "estimate, chi2, crb, diagnosis"]),
    (('distribution = "normal"', 'distribution = "cauchy"'), ['[variations."gyro.bias.z"] distribution', "normal"]),
    (('tolerance = "40 ug"', 'tolerance = "40 parsecs"'), ["acc.bias", "40 parsecs"]),
    (('method = "lsq"', 'method = "kalman"'), ["[procedures.lsq] method", "lsq, cwccw"]),
    (('systems = ["ours"]\n\n[[criteria]]\nid = "OBS"', 'systems = ["theirs"]\n\n[[criteria]]\nid = "OBS"'),
     ["systems", "ours, acme, segv, hang"]),
    (("replicates = 10", "replicates = 0"), ["[campaign] replicates", "integer >= 1"]),
    # a parameter the least squares does not estimate: refused here, not failed in every case
    (('parameters = ["acc.bias.*"]', 'parameters = ["acc.k3.*"]'),
     ["parameters = ['acc.k3.*']: procedure 'lsq' estimates none of them", "[procedures.lsq] effects"]),
])
def test_bad_campaign_files_name_file_key_and_expectation(tmp_path, campaign_file, change, words):
    text = campaign_file.read_text()
    assert change[0] in text
    p = _write(tmp_path, text.replace(change[0], change[1], 1))
    with pytest.raises(CampaignError) as e:
        load_campaign(p)
    msg = str(e.value)
    assert str(p) in msg
    for w in words:
        assert w in msg, msg


def test_criteria_verdicts():
    est = {"acc.bias.x": {"value": 1e-4, "sigma": 1e-5, "truth": 0.0, "error": 1e-4, "crb": 1e-5}}
    crit = {"id": "A", "requirement": "R", "kind": "estimate", "parameters": ["acc.bias.*"]}
    assert not evaluate({**crit, "tolerance": "5 ug"}, {"estimates": est})["passed"]
    assert evaluate({**crit, "tolerance": "20 ug"}, {"estimates": est})["passed"]
    r = evaluate({**crit, "crb_sigmas": 5}, {"estimates": est})
    assert not r["passed"] and "CRB" in r["message"]
    assert not evaluate({**crit, "parameters": ["gyro.*"], "sigmas": 3}, {"estimates": est})["passed"]
    assert evaluate({"id": "C", "requirement": "R", "kind": "crb", "parameters": ["acc.bias.x"], "max": "2 ug"},
                    {"estimates": est})["passed"]
    assert not evaluate({"id": "X", "requirement": "R", "kind": "chi2", "max": 1.5}, {"chi2_per_dof": 2.0})["passed"]
    assert evaluate({"id": "D", "requirement": "R", "kind": "diagnosis", "verdict": "none"},
                    {"diagnosis": None})["passed"]
    assert not evaluate({"id": "D", "requirement": "R", "kind": "diagnosis", "verdict": "none"},
                        {"diagnosis": "acc.k2"})["passed"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="case servers fork on Linux only")
def test_case_child_dies_with_its_worker(campaign_file, tmp_path):
    """A worker killed while its case hangs (the campaign interrupted, a machine going down) takes
    the case's process with it: no orphan left spinning (found: one ran on at 90 % CPU)."""
    from components.campaign.isolate import _Server
    from components.campaign.spec import task_for

    camp = load_campaign(campaign_file)
    task = task_for(camp, next(c for c in camp.cases if c.id.startswith("lsq-hang")))
    (tmp_path / "task.json").write_text(json.dumps(task))
    server = _Server()
    # the case's temporary files where run_isolated puts them, in a directory of the case's own
    # (the test left its killed child's two unpacked FMUs in the machine's temporary directory)
    (tmp_path / "tmp").mkdir()
    req = {"task": str(tmp_path / "task.json"), "result": str(tmp_path / "r.json"),
           "stderr": str(tmp_path / "err.txt"), "tmpdir": str(tmp_path / "tmp"), "timeout": 600}
    server.p.stdin.write((json.dumps(req) + "\n").encode())
    server.p.stdin.flush()
    children = Path(f"/proc/{server.p.pid}/task/{server.p.pid}/children")
    deadline = time.monotonic() + 30
    kids: list[int] = []
    while time.monotonic() < deadline and not kids:
        kids = [int(k) for k in children.read_text().split()]
        time.sleep(0.05)
    assert kids, "the case server forked no child"
    time.sleep(1.0)  # the child is inside the hanging FMU now
    server.close()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and Path(f"/proc/{kids[0]}").exists():
        status = Path(f"/proc/{kids[0]}/status")
        if status.exists() and "State:\tZ" in status.read_text():
            break
        time.sleep(0.05)
    status = Path(f"/proc/{kids[0]}/status")
    survived = status.exists() and "State:\tZ" not in status.read_text()
    if survived:
        os.kill(kids[0], signal.SIGKILL)  # leave no spinning process to the other tests
    assert not survived, "the case child outlived its server"


@pytest.mark.parametrize("isolation", ["fork", "spawn"])
def test_a_case_runs_its_chunk_work_and_blas_on_one_process(tmp_path, monkeypatch, isolation):
    """Whatever the caller's environment asks, a case's process has one chunk worker and one BLAS
    thread: the campaign's workers are the parallelism (a case forking a chunk worker per CPU
    beside them oversubscribes the machine). Read from the environment the case process gets."""
    from components.campaign import isolate

    for name, value in (("CALBENCH_WORKERS", "2"), ("OPENBLAS_NUM_THREADS", "4")):
        monkeypatch.setenv(name, value)
    if isolation == "fork":
        if not isolate._use_server():
            pytest.skip("case servers fork on Linux only")
        server = isolate._Server()
        try:
            raw = Path(f"/proc/{server.p.pid}/environ").read_bytes()
        finally:
            server.close()
        env = dict(item.split("=", 1) for item in raw.decode().split("\0") if "=" in item)
    else:
        seen = {}

        def run(cmd, env, **kwargs):
            seen.update(env)
            return subprocess.CompletedProcess(cmd, 0)

        monkeypatch.setattr(isolate.subprocess, "run", run)
        isolate._spawn(tmp_path / "in.json", tmp_path / "out.json", tmp_path / "err.txt", tmp_path, 10.0)
        env = seen
    assert env["CALBENCH_WORKERS"] == "1" and env["OPENBLAS_NUM_THREADS"] == "1"


@pytest.mark.parametrize("isolation", ["fork", "spawn"])
def test_killed_case_leaves_no_temporary_files(campaign_file, tmp_path, monkeypatch, isolation):
    """A case killed at its timeout runs no clean-up of its own: what it unpacked (its FMUs) must
    still go with it. Found: two unpacked FMUs left in the temporary directory per killed case."""
    from components.campaign import isolate
    from components.campaign.spec import task_for

    if isolation == "fork" and not isolate._use_server():
        pytest.skip("case servers fork on Linux only")
    temp = tmp_path / "temp"
    temp.mkdir()
    # this process and every process it starts (a fresh case server, a spawned case) use *temp*
    monkeypatch.setenv("TMPDIR", str(temp))
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    monkeypatch.setenv("CALBENCH_CASE_ISOLATION", isolation)
    monkeypatch.setattr(isolate, "_pool", [])
    camp = load_campaign(campaign_file)
    task = task_for(camp, next(c for c in camp.cases if c.id.startswith("lsq-hang")))
    try:
        rec = isolate.run_isolated(task, timeout_s=10.0 if isolation == "spawn" else 4.0)
    finally:
        for server in isolate._pool:
            server.close()
    assert "timeout" in rec["reason"], rec["reason"]
    assert sorted(p.name for p in temp.iterdir()) == []


def test_existing_cluster_by_address_gives_the_same_records(campaign_file, two_workers, tmp_path):
    """`--scheduler ADDRESS`: a Dask cluster started on its own (`dask scheduler`, `dask worker`
    as an operator would), no other change: the same verdicts and byte-identical records."""
    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    def dask(cli: str) -> list[str]:  # `dask scheduler` / `dask worker`, with this interpreter
        return [sys.executable, "-m", f"distributed.cli.dask_{cli}"]

    procs = [subprocess.Popen([*dask("scheduler"), "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(sched_file)],
                              cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not sched_file.exists():
            time.sleep(0.1)
        assert sched_file.exists(), "the scheduler did not start"
        address = json.loads(sched_file.read_text())["address"]
        procs.append(subprocess.Popen([*dask("worker"), address, "--nworkers", "2", "--nthreads", "1",
                                       "--no-dashboard"], cwd=tmp_path, env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=60)
        out = tmp_path / "remote"
        assert cli_main(["campaign", str(campaign_file), "--out", str(out), "--scheduler", address,
                         "--pages", "0"]) == 0
        ref = {p.name: p.read_bytes() for p in (two_workers / "cases").glob("*.json")}
        got = {p.name: p.read_bytes() for p in (out / "cases").glob("*.json")}
        assert sorted(got) == sorted(ref)
        assert [n for n in ref if got[n] != ref[n]] == []
        session = json.loads((out / "manifest.json").read_text())["sessions"][0]
        assert session["scheduler"] == address and session["workers"] is None
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()


def test_a_campaign_cluster_takes_a_free_port_not_8787():
    """The campaign's local cluster serves HTTP on a port of its own: with 8787 taken (another
    campaign, a notebook's cluster) it starts without a warning (there was one, "Port 8787 is
    already in use", which also hung the command: test_cli_scripts)."""
    import socket
    import warnings

    from components.campaign.execute import connect

    taken = socket.socket()
    try:
        try:
            taken.bind(("", 8787))
            taken.listen(1)
        except OSError:
            pass  # already taken by something else: the same situation
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            client, cluster, slots = connect(workers=1)
            try:
                port = cluster.scheduler.http_server.port
            finally:
                client.close()
                cluster.close()
        assert slots == 1 and port != 8787
        assert not [w for w in seen if "8787" in str(w.message)], [str(w.message) for w in seen]
    finally:
        taken.close()
