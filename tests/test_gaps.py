"""A sample after a gap spans the gap: it is left out of every estimate, and so of every statistic
of the residual too. Checked on the conformance log with 100 samples dropped inside a rest
(measured timing: the gap is found from the time stamps): compare's per-channel RMS and noise
floor and the identified white levels are those of the log without the gap (within their own
sampling spread, a few per cent), where the gap's sample had put a vendor log's gyro RMS/noise
at 1.36 and a counts channel's white level 2000 times too high."""
from __future__ import annotations

import dataclasses

import numpy as np

from components.diagnosis.compare import compare
from components.diagnosis.noise_id import identify_noise
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS
from components.model.result import result_from_fit


def _with_gap(log, drop: int = 100):
    """*log* as measured timing with *drop* samples missing from the middle of its longest rest."""
    d = LogData.from_log(log)
    st = np.concatenate([[False], d.static, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(st))
    a, b = max(zip(edges[::2], edges[1::2]), key=lambda r: r[1] - r[0])
    mid = (a + b) // 2
    keep = np.ones(log.n, bool)
    keep[mid:mid + drop] = False

    def cut(x):
        return None if x is None else x[keep]

    out = dataclasses.replace(log, time=log.time[keep], gimbal={k: v[keep] for k, v in log.gimbal.items()},
                              command={k: v[keep] for k, v in log.command.items()}, gyro=log.gyro[keep],
                              acc=log.acc[keep], temperature=cut(log.temperature), segment=cut(log.segment),
                              mask=cut(log.mask), timing="measured", angle_matrix=None)
    # the records the logger missed are lost: the sample after the gap holds its own increment
    # while its interval spans the gap (the model's prediction over it is ~100 samples' worth)
    return out


def _model(data):
    fit = calibrate(data, list(DEFAULT_EFFECTS))
    return result_from_fit(fit, list(DEFAULT_EFFECTS), data, None)


def test_the_sample_after_a_gap_enters_no_statistic(conformance):
    log = read_log(conformance / "example")
    whole, gapped = LogData.from_log(log), LogData.from_log(_with_gap(log))
    assert int((~gapped.usable).sum()) == 1  # the sample after the gap, and only it
    cw, cg = (compare(d, _model(d)) for d in (whole, gapped))
    for ch in cw.channels:
        assert abs(cg.channels[ch]["rms"] / cw.channels[ch]["rms"] - 1) < 0.05, ch
        assert abs(cg.channels[ch]["noise_floor"] / cw.channels[ch]["noise_floor"] - 1) < 0.05, ch
    nw, ng = (identify_noise(d, _model(d), slow=False, bootstrap=5) for d in (whole, gapped))
    for a, b in zip(nw.model.channels, ng.model.channels):
        assert abs(b.white / a.white - 1) < 0.05, (a.white, b.white)
