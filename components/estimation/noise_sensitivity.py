"""How much the σ of a calibration rests on the noise terms its log cannot pin down.

Noise identification keeps a bias-instability floor or a random walk only when the log shows it
(components.diagnosis.noise_id); an absent term has an upper bound instead, the magnitude the
likelihood still allows. A term below detection can still matter: on a 36-minute 26-position
log a navigation-grade gyro floor of 0.003 °/h is not detected, yet under it the gyro biases' σ
is 1.5 times the one the identified (white) model gives (benchmarks/
coloured_noise_26position_navigation.txt). So beside the σ under the identified model, calibrate
gives each parameter's σ with every absent slow term at its bound: the range the honest σ lies in
when the log cannot tell. The same holds for a pulse channel's white level that the block sums
bound only from above (read at their one-σ limit, beside a slow term that took their scatter):
it goes in at its three-σ upper limit."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from components.estimation.noise_likelihood import FLICKER_CORNER_TEST
from components.estimation.stacked_qr import scaled_lstsq
from components.estimation.whitening import whitened_r
from components.model.noise import NoiseModel, term_name

SLOW_TERMS = ("bias_instability", "random_walk")


def at_upper_bounds(identification) -> tuple[NoiseModel | None, list[str]]:
    """The identified model with every slow term it found absent at its upper bound (a floor
    with its lower corner where its presence was tested), and every white level it read at the
    block sums' one-σ limit (a pulse channel whose counts hide it beside a slow term) at its
    three-σ upper limit; and which terms those are ("gyro_x bias_instability", "acc_y white",
    ...); (None, []) when there are none."""
    chans = list(identification.model.channels)
    added = []
    for k, c in enumerate(identification.channels):
        white_iv = identification.model.intervals.get(term_name(k, "white"))
        if white_iv is not None and "white" in c.present and not np.isfinite(c.sigma.get("white", np.nan)) \
                and np.isfinite(white_iv[1]) and white_iv[1] > chans[k].white:
            chans[k] = replace(chans[k], white=float(white_iv[1]))
            added.append(f"{c.name} white")
        for t in SLOW_TERMS:
            rep = c.slow.get(t)  # absent from the report: the likelihood stage did not run
            if not rep or rep.get("present") or not np.isfinite(rep.get("upper", np.nan)):
                continue
            extra = {t: float(rep["upper"])}
            if t == "bias_instability":
                extra["flicker_range"] = (FLICKER_CORNER_TEST, None)
            chans[k] = replace(chans[k], **extra)
            added.append(f"{c.name} {t}")
    if not added:
        return None, []
    m = identification.model
    return replace(m, channels=tuple(chans), source=m.source + "; terms the log cannot pin down at their upper bounds"), added


def sigma_under(fit, noise: NoiseModel, span: float, chunk_s: float = 1.0) -> np.ndarray:
    """σ of the parameters of *fit* (components.estimation.lsq.Fit) were the noise *noise*: the
    same rows, whitened with it (the generalised least-squares covariance); *span*: the log's
    duration [s]."""
    rows = fit.rows
    y, H, w = rows["y"], rows["H"], rows["weight"]
    R = whitened_r(y, H, rows, 1.0 / w**2, noise, fit.dt, span, chunk_s)
    cov = scaled_lstsq(R[:, :-1], R[:, -1], None)[2]
    return np.sqrt(np.clip(np.diag(cov), 0, None))


def sensitivity(fit, identification, span: float, chunk_s: float = 1.0) -> dict | None:
    """For a result's ``noise_sensitivity``: the absent slow terms put at their bounds, and per
    parameter the σ under that model and its ratio to the reported σ; None when the
    identification left no slow term absent."""
    noise, added = at_upper_bounds(identification)
    if noise is None:
        return None
    bounded = sigma_under(fit, noise, span, chunk_s)
    return {"terms_at_upper_bound": added,
            "sigma_at_bounds": dict(zip(fit.parameters, bounded.tolist())),
            "ratio": {p: float(b / s) if s > 0 else float("nan")
                      for p, b, s in zip(fit.parameters, bounded, fit.sigma)}}
