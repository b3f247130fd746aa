"""check-fmu accepts every FMU the orchestrator can run and refuses, with the reason, only what it
cannot: model exchange only, scheduled execution only, FMI 1.0."""
from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from components.cli import main
from fmus.build import fmu_path
from orchestrator.check import check_fmu

HERE = Path(__file__).parent / "fmus"


@pytest.mark.parametrize("model", ["turntable", "imu"])
def test_accepts_our_fmi3_builds_with_their_int32_variables(model):
    verdict = check_fmu(fmu_path(model, 3))
    assert verdict.ok, verdict.report()
    # read through fmi3GetInt32 as Int32, not fmi3GetFloat64
    assert "Int32" in verdict.report() and "Float64" in verdict.report()


def test_accepts_a_test_fmu_in_both_versions():
    for version in (2, 3):
        verdict = check_fmu(fmu_path(HERE / "lag", version))
        assert verdict.ok, verdict.report()


def _rewrite(src: Path, dst: Path, old: str, new: str) -> Path:
    """A copy of *src* whose model description has *old* replaced by *new*."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                assert old in text
                data = text.replace(old, new).encode()
            zout.writestr(item, data)
    return dst


def test_refuses_model_exchange_only_with_the_reason(tmp_path, capsys):
    src = fmu_path(HERE / "lag", 3)
    me = _rewrite(src, tmp_path / "me.fmu", "<CoSimulation ", "<ModelExchange ")
    verdict = check_fmu(me)
    assert not verdict.ok
    assert "model exchange only" in verdict.cannot_run and "ODE solver" in verdict.cannot_run
    assert main(["check-fmu", str(me)]) == 1
    out = capsys.readouterr().out
    assert "cannot run in the orchestrator" in out and "REFUSED" in out


def test_refuses_scheduled_execution_only_with_the_reason(tmp_path):
    src = fmu_path(HERE / "lag", 3)
    se = _rewrite(src, tmp_path / "se.fmu", "<CoSimulation ", "<ScheduledExecution ")
    verdict = check_fmu(se)
    assert not verdict.ok
    assert "scheduled execution only" in verdict.cannot_run and "clocks" in verdict.cannot_run


def test_a_failing_step_is_refused_with_the_fmus_own_message(tmp_path, capsys):
    src = fmu_path(HERE / "failing", 2)
    failing = _rewrite(src, tmp_path / "fails_at_0.fmu", '<Real unit="s" start="1e+300"/>',
                       '<Real unit="s" start="0.0"/>')
    verdict = check_fmu(failing)
    assert not verdict.ok
    (problem,) = verdict.smoke
    assert "fmi2DoStep" in problem and "deliberate failure: step from t = 0 reached fail_time = 0" in problem
    assert capsys.readouterr().out == ""  # the FMU's log is in the verdict, not printed on the side


def test_the_smoke_test_steps_at_the_fmus_default_experiment_step(tmp_path):
    """An FMU whose maker states a DefaultExperiment step is smoke-tested at it, unless a step is
    given: the failing FMU, failing from t = 4 ms on, runs steps that start at 0 and at one step,
    so it passes at a stated 2 ms and fails at 5 ms (calbench stepped at 5 ms whatever was stated)."""
    src = fmu_path(HERE / "failing", 2)
    fails_at_4ms = _rewrite(src, tmp_path / "a.fmu", '<Real unit="s" start="1e+300"/>', '<Real unit="s" start="0.004"/>')
    unstated = _rewrite(fails_at_4ms, tmp_path / "c.fmu", '<DefaultExperiment startTime="0" stopTime="1" stepSize="0.005"/>', "")
    assert not check_fmu(unstated).ok and "calbench's default" in check_fmu(unstated).report()
    stated = _rewrite(fails_at_4ms, tmp_path / "b.fmu", 'stepSize="0.005"', 'stepSize="0.002"')
    verdict = check_fmu(stated)
    assert verdict.ok, verdict.report()
    assert "step 0.002 s: the FMU's DefaultExperiment" in verdict.report()
    forced = check_fmu(stated, step=0.005)
    assert not forced.ok and "step 0.005 s: given" in forced.report()
