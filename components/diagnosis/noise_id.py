"""Noise identification on a calibration log: which terms of the composite model
(components.model.noise) the residual shows, how large, with a σ each.

Two stages, each where its information is:

1. **Fast terms from the static runs.** The model's per-sample residual in the static runs,
   as a rate, has a pooled overlapping Allan variance (components.estimation.allan) that
   quantization, white noise and, where the runs are long enough, the start of the bias floor
   shape; the composite is fitted to it (components.estimation.noise_fit), σ by parametric
   bootstrap. Quantization of a pulse output is known from its count weight and held.
2. **Slow terms from the whole log.** Bias instability and random walk act over the whole run,
   which the block sums of the calibration show; their magnitudes (and the bias floor's lower
   corner) are estimated by restricted maximum likelihood with the fast terms held
   (components.estimation.noise_likelihood), each kept when its likelihood ratio is significant.

The model the estimators then use has only the terms found present.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from components import progress
from components.diagnosis.noise_axes import unlike_axes
from components.estimation.allan import first_runs, static_runs
from components.estimation.chunks import forked_map
from components.estimation.log_data import LogData
from components.estimation.noise_fit import BASIC, ChannelFit, identify_channel, white_ceiling
from components.estimation.noise_likelihood import (
    SLOW,
    VARIANCE_REACH,
    family_critical,
    fit_slow_terms,
    pooled_critical,
)
from components.estimation.whitening import channel_blocks
from components.logs.spill import release
from components.model.noise import (
    AXES,
    CHANNELS,
    TERM_OF_NAME,
    TERMS,
    ChannelNoise,
    NoiseModel,
    sensor_of,
    term_name,
)

ALLAN_SAMPLES = 1 << 22  # static samples the Allan stage uses, at most (70 minutes at 1 kHz)


@dataclass
class ChannelIdentification:
    name: str
    fast: ChannelFit            # the Allan-variance stage
    slow: dict                  # the likelihood stage: term -> value, sigma, likelihood_ratio, critical, present
                                # (and pooled_likelihood_ratio, pooled_critical: its sensor's axes tested together)
    noise: ChannelNoise         # the final model of the channel (present terms only)
    sigma: dict                 # term -> σ of its magnitude
    present: list
    held: tuple = ()            # terms held at a known value (a count weight's quantization, a term given)


@dataclass
class NoiseIdentification:
    model: NoiseModel
    channels: list = field(default_factory=list)
    static_runs: int = 0
    notes: list = field(default_factory=list)
    # what it says of the white levels the static runs could not show (read from the block
    # sums, or not found): the noise line says it (None: every channel's from the static runs)
    white_note: str | None = None

    def table(self) -> list[str]:
        """The identified terms per channel in readable units, with σ; absent terms with their
        upper bound."""
        lines = [f"{'channel':8s} {'term':18s} {'value':>12s} {'sigma':>10s}  unit           present  "
                 "(slow terms, and a white level bounded from above only: the 3σ profile-likelihood interval; "
                 "a slow term's presence test: its likelihood ratio against the one it must exceed)"]
        for k, c in enumerate(self.channels):
            terms = TERMS[sensor_of(k)]
            for t in BASIC:
                vname, _, dunit, scale = terms[t]
                v = getattr(c.noise, t)
                s = c.sigma.get(t, float("nan"))
                test = c.slow.get(t) if isinstance(c.slow.get(t), dict) else {}
                tested = ""
                if "pooled_critical" in test:
                    tested = (f"  LR {max(test['likelihood_ratio'], 0.0):.1f}; the {sensor_of(k)}'s axes together "
                              f"{test['pooled_likelihood_ratio']:.1f} against {test['pooled_critical']:.1f}")
                elif "critical" in test:
                    tested = f"  LR {max(test['likelihood_ratio'], 0.0):.1f} against {test['critical']:.1f}"
                if t in c.present:
                    iv = self.model.intervals.get(term_name(k, t))
                    within = f"  [{iv[0] / scale:.3g}, {iv[1] / scale:.3g}]" if iv else ""
                    sd = f"{s / scale:10.2g}" if np.isfinite(s) else f"{'-':>10s}"
                    held = " (held)" if t in c.held else ""
                    lines.append(f"{c.name:8s} {vname.split('.', 2)[2]:18s} {v / scale:12.4g} {sd}  "
                                 f"{dunit:14s} yes{held}{within}{tested}")
                else:
                    up = c.fast.upper.get(t) if t in c.fast.upper else None
                    if t in c.slow:
                        up = c.slow[t].get("upper", c.slow[t]["value"])
                    bound = f"< {up / scale:.3g}" if up is not None and np.isfinite(up) else "-"
                    lines.append(f"{c.name:8s} {vname.split('.', 2)[2]:18s} {bound:>12s} {'':10s}  {dunit:14s} no{tested}")
            if c.noise.bias_instability and c.noise.flicker_range:
                lines.append(f"{c.name:8s} {'bi floor from':18s} {c.noise.flicker_range[0]:12.3g} {'':10s}  s")
            for s_, T in c.noise.gauss_markov:
                gu = TERMS[sensor_of(k)]["bias_instability"]
                lines.append(f"{c.name:8s} {'gauss-markov':18s} {s_ / gu[3]:12.4g} {'':10s}  {gu[2]:14s} yes "
                             f"(T = {T:.3g} s)")
        return lines

    def presence_tests(self) -> dict:
        """The noise file's ``presence_tests``: per channel, each slow term's test — present, its
        likelihood ratio against the critical one (and its sensor's axes' sum against theirs,
        where they were tested together), an absent term's profile upper bound in its SI unit
        (null where not finite: JSON has no infinity)."""
        def number(v):
            return float(v) if v is not None and math.isfinite(v) else None

        out = {}
        for k, c in enumerate(self.channels):
            tests = {}
            for t in SLOW:
                test = c.slow.get(t)
                if not isinstance(test, dict):
                    continue
                e = {"present": bool(test["present"]), "likelihood_ratio": number(max(test["likelihood_ratio"], 0.0)),
                     "critical": number(test["critical"])}
                if "pooled_critical" in test:
                    e["pooled_likelihood_ratio"] = number(test["pooled_likelihood_ratio"])
                    e["pooled_critical"] = number(test["pooled_critical"])
                if not test["present"]:
                    e["upper"] = number(test.get("upper"))
                    e["unit"] = TERMS[sensor_of(k)][t][1]
                tests[t] = e
            if tests:
                out[c.name] = tests
        return out


def pooled_terms(slow_terms: list) -> list:
    """[(axes, term)]: the slow terms tested on a sensor's three axes at once — those every axis
    of the sensor tests (*slow_terms*: per channel 0-5, the terms its likelihood stage looks for).

    A triad's axes share their noise terms' presence (every gyro of a triad has a flicker floor,
    each at its own level), so the sum of the axes' likelihood ratios is the test: one axis's
    marginal floor no longer drops out alone, taking its bias's σ with it (the 2" counts log of
    an IMU FMU with a floor on every gyro, 1 % of its samples left out: gyro_y's floor dropped
    at LR 9.6 against 9.9 beside gyro_x's 36 and gyro_z's 51, and gyro.bias.y 7.5 σ off)."""
    return [(axes, t) for axes in ((0, 1, 2), (3, 4, 5)) for t in ("bias_instability", "random_walk")
            if all(t in slow_terms[k] for k in axes)]


def pooled_presence(reports: list, pooled: list, critical: float) -> tuple[list, dict]:
    """(per channel: term -> present, as the pooled tests decide; channel -> term -> what the
    test saw) for the channels' likelihood reports (fit_slow_terms) and the *pooled* (axes, term)
    tests at *critical* (components.estimation.noise_likelihood.pooled_critical).

    Where a sensor's axes pool both slow terms, the elimination each channel does alone is done
    on the sums: each term's ratio against the model with both (``elimination.against_all``),
    summed over the axes; the term whose loss the axes feel least (``elimination.loss_against_all``,
    the channel's own ranking), if its sum is below *critical*, is dropped from every axis,
    and the other is then tested by the sums of its ratios as the only term
    (``elimination.alone``). Summing each axis's ratio at the step its own elimination reached
    instead mixed tests of different models: an axis whose random walk stood in for its floor
    (ratio 76 against no term) made the random walk present on all three axes beside the floor
    the other two kept (ratios ~0.1 against it). A sensor that pools one term sums its axes'
    ratios at their own tests."""
    decided = [{} for _ in reports]
    tested: dict = {}
    for axes in dict.fromkeys(a for a, _ in pooled):
        terms = [t for a, t in pooled if a == axes]

        def total(t, which=None, axes=axes):
            """The axes' ratios of *t* summed: at their own tests, or at a step of the elimination."""
            return sum(max(float(reports[k]["elimination"][which][t] if which else reports[k][t]["likelihood_ratio"]),
                           0.0) for k in axes)

        if len(terms) == 1:
            sums = {terms[0]: total(terms[0])}
            present = {terms[0]: sums[terms[0]] > critical}
        else:
            sums = {t: total(t, "against_all") for t in terms}
            # the term the axes miss least, as each channel's own elimination ranks it: by what
            # dropping it costs against the fit with the floor's corner free, not by its test
            # ratio (the floor's, with the corner held, can be small where a corner elsewhere
            # takes a wander the random walk then stands in for)
            weakest = min(terms, key=lambda t: total(t, "loss_against_all"))
            present = {t: True for t in terms}
            if sums[weakest] <= critical:
                present[weakest] = False
                (other,) = [t for t in terms if t != weakest]
                sums[other] = total(other, "alone")
                present[other] = sums[other] > critical
        for k in axes:
            for t in terms:
                decided[k][t] = present[t]
                tested.setdefault(k, {})[t] = {"pooled_likelihood_ratio": sums[t], "pooled_critical": critical}
    return decided, tested


def at_scale(ceiling: float, scale: float) -> float:
    """The white level at a *scale* of the blocks' independent variance, from its *ceiling* (the
    level at scale 1, the most the rests allow): never above it, and the ceiling where the scale
    is not known (a likelihood limit not reached)."""
    return ceiling * math.sqrt(min(scale, 1.0) if np.isfinite(scale) else 1.0)


# static samples below which no noise term is identified: the Allan deviation then spans too few
# octaves with too few degrees of freedom to tell quantization, white noise and the slow terms apart
MIN_STATIC_SAMPLES = 200


def identify_noise(data: LogData, model, *, known: dict | None = None, terms=BASIC, bootstrap: int = 30,
                   seed: int = 0, chunk_s: float = 1.0, slow: bool = True) -> NoiseIdentification:
    """The composite noise of *data*'s six channels around the calibrated *model*
    (components.model.result.CalibrationResult). ``known``: per channel (0-5) a dict of term ->
    magnitude held (e.g. the quantization of a pulse output); ``terms``: the basic terms to look
    for; ``slow``: run the whole-log likelihood stage for bias instability and random walk."""
    from components.diagnosis.compare import compare
    from components.estimation.lsq import calibrate

    known = known or {}
    comp = compare(data, model, noise=None)
    dt = data.sample_interval
    runs = static_runs(comp.static_usable)  # a left-out sample ends a run (it may span a gap)
    if not runs:
        raise ValueError("no static run of 8 samples or more: the noise cannot be identified from this "
                         "log (give it with --noise NAME=VALUE)")
    span = float(data.time[-1] - data.time[0] + dt)
    notes = []
    # the fast terms from the first ALLAN_SAMPLES static samples: they show at short τ, which an
    # hour of rests measures well, and the bootstrap simulates the record up to the last run used
    # (on an 8-hour 1 kHz log, 30 M samples per replicate and a flicker range past what its
    # Gauss–Markov sum can realise)
    used = first_runs(runs, ALLAN_SAMPLES)
    total = sum(b - a for a, b in used)
    if total < MIN_STATIC_SAMPLES:
        # (ten samples gave a quantization 'present' on an increment output and upper bounds
        # below the true white level, with exit 0)
        raise ValueError(f"the static runs hold {total} samples ({total * dt:.3g} s): too few to tell the noise "
                         f"terms apart (at least {MIN_STATIC_SAMPLES}); give the noise with --noise (a grade, a "
                         "noise file, NAME=VALUE terms)")
    upto = used[-1][1]
    if len(used) < len(runs):
        notes.append(f"quantization and white noise from the first {total} static samples (the log's first "
                     f"{upto * dt / 60:.0f} minutes); the slow terms from the whole log")
    # the channels are independent (each bootstrap from its own seed), so they run on the chunk
    # workers with the same bits as one after the other
    def fast_channel(k: int) -> ChannelFit:
        out = identify_channel(comp.residual[:upto, k] / dt, used, dt, terms=tuple(terms),
                               known=known.get(k), bootstrap=bootstrap, seed=seed + k)
        release(comp.residual)
        return out

    with progress.steps("noise: Allan variance per channel", 6) as bar:
        fast = forked_map(fast_channel, 6, bar)
    chans = [f.noise for f in fast]
    out_channels = []
    rows = None
    # channels whose static runs showed no white level (pulse counts much coarser than a sample's
    # noise hide it at short τ, and the Allan variance has no τ long enough to read it beside the
    # floor): the whole log's block sums show it as the scatter that accumulates over a rest where
    # the counts' remainder does not, so the likelihood stage measures it, as the scale of the
    # blocks' independent variance from the most the Allan variance allows (its ceiling)
    hidden = [k for k in range(6) if not chans[k].white > 0 and "white" not in (known.get(k) or {})]
    if slow:
        white = np.array([c.white if k not in hidden else white_ceiling(fast[k].allan)
                          for k, c in enumerate(chans)]) * math.sqrt(dt)
        fit = calibrate(data, list(model.effects), chunk_s=chunk_s, sigma_gyro=white[:3], sigma_acc=white[3:],
                        temperature_ref=model.temperature_ref)
        rows = fit.rows
    # the slow terms are tested on every channel: 1 % for the whole identification (Bonferroni),
    # not for each of its tests (12 tests at 1 % each name a term that is not there on 11 % of
    # logs, and a term named by chance comes at several times any true size, with the σ of every
    # estimate it touches)
    slow_terms = [[t for t in ("bias_instability", "random_walk") if t in terms and t not in (known.get(k) or {})]
                  for k in range(6)]
    pooled = pooled_terms(slow_terms)
    tests = sum(map(len, slow_terms)) - 2 * len(pooled)  # (a pooled test stands for its three axes' tests)
    critical = family_critical(tests)

    def slow_channel(k: int, decided: dict | None = None, fits: dict | None = None) -> tuple[ChannelNoise, dict, dict]:
        b = channel_blocks(rows, k, dt, rows["y"], rows["H"], rows["weight"])
        # (a slow term held at a given value stays in the base the others are fitted beside)
        base = replace(chans[k], gauss_markov=(), **{t: 0.0 for t in ("bias_instability", "random_walk")
                                                     if t not in (known.get(k) or {})})
        # (the count remainder as independent here, not turning: the advance read from the same
        # counts sets part of what the block sums show, and the white level the scale measures
        # came out low with it — gyro_x 4.7e-7 for 5.8e-7 on 2" counts, within 3σ on 12 of 20
        # logs, a false verdict on 6 of 20 with the datasheet's slow terms over it; independent,
        # 6.7e-7 and 19 of 20, no false verdict)
        fits = {} if fits is None else fits  # (the maximisations, back from a forked worker for a refit)
        return (*fit_slow_terms(base, b.y, b.H, b.durations, b.white_var, span, chunk_s, slow_terms[k],
                                critical=critical, variance_bound=k in hidden, gaps=b.gaps, decided=decided,
                                fits=fits), fits)

    with progress.steps("noise likelihood per channel", 6 if rows is not None else 0) as bar:
        slow_fits = forked_map(slow_channel, 6, bar) if rows is not None else [(c, {}, {}) for c in chans]
    if rows is not None and pooled:
        decided, tested = pooled_presence([r for _, r, _ in slow_fits], pooled, pooled_critical(3, tests))
        redo = [k for k in range(6) if any(slow_fits[k][1][t]["present"] != v for t, v in decided[k].items())]
        with progress.steps("noise likelihood, the pooled tests' channels", len(redo)) as bar:
            again = forked_map(lambda i: slow_channel(redo[i], decided[redo[i]], slow_fits[redo[i]][2]), len(redo),
                               bar)
        for k, fit_k in zip(redo, again):
            slow_fits[k] = fit_k
        for k, by_term in tested.items():
            for t, test in by_term.items():
                slow_fits[k][1][t].update(test)
    read_from_blocks, at_one_sigma, white_interval = [], [], {}
    for k, (ch, report, _) in enumerate(slow_fits):
        sigma, present = dict(fast[k].sigma), list(fast[k].present)
        if rows is not None:  # the slow terms are the likelihood stage's, not the Allan stage's
            present = [t for t in present if t in ("quantization", "white")] + \
                [t for t in slow_terms[k] if report[t]["present"]] + \
                [t for t in ("bias_instability", "random_walk") if t in (known.get(k) or {})]
            sigma.update({t: report[t]["sigma"] for t in slow_terms[k]})
            if k in hidden:
                ceiling = white[k] / math.sqrt(dt)  # (white_ceiling: no level above it)
                level = at_scale(ceiling, report["block_variance_scale"])
                # σ of N from that of log N² (half of it). Kept wherever the likelihood has its
                # maximum inside the scale's reach (a finite curvature), even below three σ: as in
                # the Allan stage, every sensor has white noise, and a level poorly read is not
                # an absent one (dropped below three σ, 7 of 20 navigation-grade logs of 1 mm/s
                # counts had the accelerometers weighed by a numerical floor: σ of acc.sf and
                # acc.mis 1.5-3x too small, an effect named on 5 of the 20). A noise-free pulse
                # output's scale runs to the edge of its reach, where the curvature is 0. Beside a
                # floor that takes the blocks' scatter, the scale ran to e^-22 with a log-σ of
                # 1.5e4, there from the numerical curvature of a flat: the scale's 3σ interval
                # must lie within its reach, so that the log bounds the level on both sides.
                log_sd = report["block_variance_log_sigma"]
                sd = level * log_sd / 2.0
                bounded = abs(math.log(report["block_variance_scale"])) + 3.0 * log_sd < VARIANCE_REACH
                if np.isfinite(sd) and sd > 0 and bounded:
                    ch = replace(ch, white=level)
                    present.append("white")
                    sigma["white"] = sd
                    read_from_blocks.append(CHANNELS[k])
                elif any(report[t]["present"] for t in slow_terms[k]):
                    # a slow term took the blocks' scatter and left them nothing to bound the
                    # white level by from below: their one-σ likelihood limit, at most the
                    # ceiling (with none, 10 µrad counts beside a 0.05 °/h gyro floor had gyro_z
                    # weighed by its quantization and floor alone, and the user told σ may be too
                    # small; with the ceiling, χ²/dof 0.74 on that log). Meant as an upper bound,
                    # it is a fair reading instead: 0.52-1.49 times the truth (median 0.94) on the
                    # coarse-count benchmark's 41 such levels of 60 logs, the truth below it in 15
                    # (benchmarks/coloured_noise_counts_coarse_diagnosis_60seeds.txt)
                    ch = replace(ch, white=at_scale(ceiling, report.get("block_variance_upper", math.nan)))
                    present.append("white")
                    sigma["white"] = float("nan")  # no measurement's σ (the Allan stage's σ is of no level)
                    # what the log does say of it: the three-σ upper limit (deviance 9), at most
                    # the ceiling; from below nothing but 0
                    white_interval[k] = (0.0, at_scale(ceiling, report.get("block_variance_upper_3sigma", math.nan)))
                    at_one_sigma.append(CHANNELS[k])
        out_channels.append(ChannelIdentification(CHANNELS[k], fast[k], report, ch, sigma, present,
                                                  tuple(known.get(k) or ())))
    sig, iv = {}, {}
    for k, c in enumerate(out_channels):
        for t in c.present:
            if t in TERMS[sensor_of(k)]:
                name = term_name(k, t)
                sig[name] = c.sigma.get(t, float("nan"))
                if "interval" in c.slow.get(t, {}):  # a slow term present in the likelihood stage
                    iv[name] = c.slow[t]["interval"]
                elif t == "white" and k in white_interval:
                    iv[name] = white_interval[k]
    model_out = NoiseModel(tuple(c.noise for c in out_channels), "identified from this log's residual", sig, iv)
    said = []
    if read_from_blocks:
        # (a level within three σ of 0 is kept, as every sensor has white noise, but not measured:
        # read low it leaves σ too small, and calibrate warns where χ²/dof then says so)
        poor = [ch for ch in model_out.white_poorly_read() if ch in read_from_blocks]
        said.append(f"white noise on {', '.join(read_from_blocks)} from the whole log's block sums (the static "
                    "runs' Allan variance cannot show it beside the counts' quantization)"
                    + (f"; on {', '.join(poor)} within three of its σ of 0, poorly read" if poor else ""))
    if at_one_sigma:
        said.append(f"white noise on {', '.join(at_one_sigma)} read at the block sums' one-σ likelihood limit (beside "
                    "the floor or random walk they found, they do not bound it from below; on simulated coarse "
                    "counts that reading lands at 0.5-1.4 times the true level, so it is no upper bound; the "
                    "interval is [0, their three-σ limit]): σ that rest on it carry that uncertainty")
    none = [CHANNELS[k] for k, c in enumerate(out_channels) if not c.noise.white > 0]
    if none:
        said.append(f"no white-noise level found on {', '.join(none)} (on a pulse output, counts much coarser "
                    "than a sample's noise hide it)" + ("" if rows is not None else ": the slow terms were not "
                    "estimated") + ", and σ that rest on it may be too small; give the noise with --noise (a "
                    "datasheet's terms, a grade or a noise file)")
    said += unlike_axes(out_channels, iv)
    notes += said
    return NoiseIdentification(model_out, out_channels, len(runs), notes, "; ".join(said) or None)


def add_noise_terms(data: LogData, model, noise: NoiseModel | None, terms: list[str], *, chunk_s: float = 1.0):
    """*noise* (None: white noise at the data's level) with the noise *terms* (``acc.noise.bi``,
    ``gyro.noise.rrw``, ...) added, each magnitude estimated per axis by restricted maximum
    likelihood on *model*'s rows. Returns (the new model, per term and axis: value, σ,
    likelihood ratio, present)."""
    from components.estimation.lsq import calibrate

    dt = data.sample_interval
    span = float(data.time[-1] - data.time[0] + dt)
    fit = calibrate(data, list(model.effects), chunk_s=chunk_s, temperature_ref=model.temperature_ref, noise=noise)
    rows = fit.rows
    if noise is None:
        noise = NoiseModel.white(np.concatenate([fit.sigma_gyro, fit.sigma_acc]), dt, "white noise")
    chans = list(noise.channels)
    report = {}
    for term in terms:
        sensor, _, t = term.split(".")
        field_ = TERM_OF_NAME[t]
        for k in (range(3) if sensor == "gyro" else range(3, 6)):
            b = channel_blocks(rows, k, dt, rows["y"], rows["H"], rows["weight"])
            ch, rep = fit_slow_terms(replace(chans[k], **{field_: 0.0}), b.y, b.H, b.durations, b.white_var, span,
                                     chunk_s, [field_], gaps=b.gaps)
            r = rep[field_]
            chans[k] = replace(ch, **{field_: r["value"]})
            report[f"{term}.{AXES[k % 3]}"] = r
    src = (noise.source + "; " if noise.source else "") + "+ " + ", ".join(terms)
    # the σ and interval a term had before are not this estimate's: the new ones, or none
    sigmas = {k: v for k, v in noise.sigmas.items() if k not in report}
    intervals = {k: v for k, v in noise.intervals.items() if k not in report}
    for name, r in report.items():
        if r["present"]:
            sigmas[name] = r["sigma"]
            intervals[name] = r["interval"]
    return replace(noise, channels=tuple(chans), source=src, sigmas=sigmas, intervals=intervals), report
