"""Noise terms as candidates of the diagnosis: a model can lack a bias-instability floor or a random
walk as it can lack an effect. Each missing term is fitted per axis by maximum likelihood on the
base model's block rows (components.estimation.noise_likelihood), with its likelihood gain,
Akaike's gain and significance, so the diagnosis can weigh it against the effects
(components.diagnosis.diagnose)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from components import progress
from components.estimation.distributions import chi2_isf
from components.estimation.noise_likelihood import fit_one_term
from components.estimation.whitening import advance_of, block_timing, channel_rows
from components.logs.spill import gathered
from components.model.noise import TERM_OF_NAME, NoiseModel

# noise terms a model can lack: (vocabulary name, channels, ChannelNoise field)
NOISE_CANDIDATES = ("acc.noise.bi", "acc.noise.rrw", "gyro.noise.bi", "gyro.noise.rrw")


def has_term(noise: NoiseModel | None, term: str) -> bool:
    """Every axis of the sensor has the term already."""
    if noise is None:
        return False
    sensor, _, t = term.split(".")
    chans = noise.channels[:3] if sensor == "gyro" else noise.channels[3:]
    return all(getattr(c, TERM_OF_NAME[t]) > 0 for c in chans)


def noise_candidates(design, base: list[str], noise: NoiseModel | None, terms, alpha: float) -> list:
    """Each missing noise term fitted by maximum likelihood on the base model's rows, channel by
    channel (the axes that lack it): its magnitudes, the log-likelihood gain, Akaike's gain (minus
    one per axis fitted), significance (likelihood ratio against the 1 % point of χ² with a degree
    of freedom per axis fitted, conservative on the boundary) and the noise model with it."""
    y, H, w, rows = design.raw
    cols = [design.index[p] for p in base]
    base_rows: dict = {}  # channel -> (its rows, their base columns), gathered once for every term
    current = noise if noise is not None else NoiseModel.white(design.white_sigma, design.dt, "white noise")
    out = []
    with progress.steps("noise terms", len(terms)) as bar:
        for term in terms:
            sensor, _, t = term.split(".")
            field_ = TERM_OF_NAME[t]
            chans = list(current.channels)
            gain, values, n_new = 0.0, [], 0
            for k in (range(3) if sensor == "gyro" else range(3, 6)):
                if getattr(chans[k], field_) > 0:  # this axis has it already
                    values.append(getattr(chans[k], field_))
                    continue
                n_new += 1
                if k not in base_rows:
                    idx = channel_rows(rows, k)
                    base_rows[k] = idx, gathered(H, idx, cols)
                idx, Hc = base_rows[k]
                active = np.any(Hc != 0, axis=0)
                durations, gaps = block_timing(rows, idx, design.dt)
                value, g = fit_one_term(chans[k], field_, y[idx], Hc[:, active], durations, 1.0 / w[idx] ** 2,
                                        design.span, design.t_lo, advance=advance_of(rows, idx), gaps=gaps)
                chans[k] = replace(chans[k], **{field_: value})
                gain += g
                values.append(value)
            lr = 2 * gain
            out.append({"term": term, "values": values, "loglik_gain": gain, "aic_gain": gain - n_new,
                        "likelihood_ratio": lr, "significant": bool(lr > chi2_isf(alpha, max(n_new, 1))),
                        "model": NoiseModel(tuple(chans), (current.source + "; " if noise is not None else "")
                                            + f"+ {term}", current.sigmas)})
            bar.update()
    out.sort(key=lambda n: -n["aic_gain"])
    return out
