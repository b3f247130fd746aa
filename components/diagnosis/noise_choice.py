"""Which noise model an estimate, a comparison or a diagnosis uses, from what the user said —
never a silent guess: the choice comes back with a sentence saying what was assumed.

Specifications, applied in order (``--noise`` on the command line, repeatable):

- ``identify``: identified on this log (components.diagnosis.noise_id), around the given model
  or, without one, around a white-noise fit of the default effects;
- ``navigation`` / ``tactical``: a typical grade's noise (components.model.noise.grade);
- a ``.json`` file: a noise file (``calbench-noise/1``, written by ``calbench noise --out``) or a
  calibration result holding a composite model;
- ``NAME=VALUE``: one term by hand, on top of what came before, e.g. ``acc.noise.bi=10 ug``,
  ``gyro.noise.arw=0.002 deg/sqrt(h)``, ``acc.noise.q.x=1e-5`` (SI without a unit); beside
  ``identify`` each such term is also held at its value while the rest is identified (a
  datasheet's ARW where pulse counts hide the white level: the slow terms are then read beside
  the true level, not beside one read low and replaced after);
- ``white``: white noise, its level from the data's sample-to-sample differences; on a pulse
  output, white noise plus the count weight's quantization as a term of its own (white_noise_model).

Without any: a model's own composite noise if it has one; a log of pulse counts with table
angles gets its quantization from the count weights and the rest identified from the static
runs; otherwise white noise as ``white`` above.
"""
from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from components.errors import UserError
from components.model.noise import AXES, FORMAT, TERM_OF_NAME, TERMS, ChannelNoise, NoiseModel, from_terms, grade
from components.model.quantities import NOISE_TERM_UNITS, QuantityError, quantity

WHITE = "white noise, its level from the static data's sample-to-sample differences"


def _term(spec: str) -> tuple[str, float]:
    name, _, value = spec.partition("=")
    name, value = name.strip(), value.strip()
    base = ".".join(name.split(".")[:3])
    if base not in NOISE_TERM_UNITS:
        raise UserError(f"--noise {spec!r}: unknown term {name!r}; expected one of {', '.join(NOISE_TERM_UNITS)} "
                        "(optionally with .x/.y/.z)")
    si, units = NOISE_TERM_UNITS[base]
    if _is_float(value) and float(value) != 0 and si != "s":
        # taken as SI, 0.005 for an ARW is 17 deg/sqrt(h): a datasheet number without its unit is
        # almost never SI (0 is 0 in any unit; time constants are seconds)
        raise UserError(f"--noise {spec!r}: a number without its unit; write it with one, e.g. "
                        f"{name}='{value} {next(iter(units))}' (units: {', '.join(units)}; SI: {si})")
    try:
        v = quantity(float(value) if _is_float(value) else value, name, "--noise", units, si)
    except QuantityError as e:
        raise UserError(str(e)) from None
    if not (v >= 0 and math.isfinite(v)):
        raise UserError(f"--noise {spec!r}: expected a magnitude >= 0")
    return name, v


def held_terms(specs) -> dict:
    """Per channel (0-5) the noise terms the NAME=VALUE *specs* give (term -> SI magnitude; a
    name without an axis on all three), for an identification to hold (terms_by_channel)."""
    given = {}
    for spec in specs or []:
        if "=" not in spec:
            continue
        name, v = _term(spec.strip())
        try:
            from_terms({name: v})   # (its name checked as a model's term: .w or a fifth part, one error)
        except ValueError as e:
            raise UserError(f"--noise {spec!r}: {e}") from None
        given[name] = v
    return terms_by_channel(given)


def terms_by_channel(terms: dict) -> dict:
    """Per channel (0-5) the named *terms* (``{"gyro.noise.arw": N, "acc.noise.bi.y": B}``, SI) as
    ChannelNoise fields: what an identification holds. The flicker range's bounds are not terms of
    the fit and are left to be applied after it."""
    held: dict = {}
    for name, v in terms.items():
        parts = name.split(".")
        if parts[2] not in TERM_OF_NAME:
            continue
        off = 0 if parts[0] == "gyro" else 3
        for a in ([AXES.index(parts[3])] if len(parts) == 4 else range(3)):
            held.setdefault(off + a, {})[TERM_OF_NAME[parts[2]]] = float(v)
    return held


def identification_known(data, held: dict | None = None) -> dict:
    """Per channel the terms an identification of *data* holds: a pulse output's quantization
    from its count weight, and the *held* terms (per channel, held_terms / terms_by_channel),
    which win."""
    known = {k: dict(v) for k, v in quantization_known(data).items()}
    for k, terms in (held or {}).items():
        known.setdefault(k, {}).update(terms)
    return known


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def load_noise_file(path: str | Path) -> NoiseModel:
    """A noise model from a noise file or from a result file's composite block; a file whose
    model is not well formed is refused naming the key (a typed term or a missing channel must
    not leave a channel's noise silently out)."""
    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except (OSError, ValueError) as e:
        raise UserError(f"--noise {p}: cannot read a JSON noise file ({e})") from None
    if isinstance(d, dict) and d.get("format") == FORMAT:
        block, at = d, ""
    elif isinstance(d, dict) and isinstance(d.get("noise"), dict) and "composite" in d["noise"]:
        block, at = d["noise"]["composite"], "noise.composite."
    else:
        raise UserError(f"--noise {p}: expected a noise file (format {FORMAT!r}, from `calbench noise --out`) or a "
                        "calibration result with a composite noise model")
    try:
        return NoiseModel.from_dict(block)
    except ValueError as e:
        raise UserError(f"--noise {p}: {at}{e}") from None


def quantization_known(data) -> dict:
    """Per channel, the quantization of a pulse output from its count weight (w / √12)."""
    out = {}
    for s, w in enumerate(data.count_weight):
        if w:
            for a in range(3):
                out[3 * s + a] = {"quantization": float(w) / math.sqrt(12.0)}
    return out


IDENTIFIED = "identified on this log"  # how a noise model identified on the log says so


def choose_noise(specs: list[str] | None, data, model=None, effects=None, *, bootstrap: int = 30,
                 base: NoiseModel | None = None):
    """(noise model or None for white, the sentence saying what it is, the identification if one
    ran) for *data*, given the user's *specs*, the calibrated *model* if any, and the *effects*
    a model would be fitted with; *base*: the model the specifications start from."""
    specs = list(specs or [])
    ident = None
    if not specs:
        if model is not None and model.noise_model() is not None:
            return with_count_quantization(model.noise_model(), data,
                                           f"the model's own: {model.noise_model().source}") + (None,)
        if data is not None and getattr(data, "noise", None):
            own = NoiseModel.from_dict(data.noise)
            return with_count_quantization(own, data, "the log's own (imu.noise)") + (None,)
        if any(data.count_weight) and data.has_table:
            specs = ["identify"]
            lead = "pulse counts: quantization from the count weights, the rest "
        else:
            noise, said = white_noise_model(data)
            return noise, said, None
    else:
        lead = ""
    noise: NoiseModel | None = base
    said = [base.source] if base is not None else []
    quantized = set()   # the sensors whose quantization the user named (kept as named)
    for spec in specs:
        s = spec.strip()
        if s == "white":
            noise, what = white_noise_model(data)
            said = [what]   # a whole model: what came before is replaced
        elif s in ("navigation", "tactical"):
            noise = grade(s)
            said = [f"{s} grade (given)"]
        elif s == "identify":
            from components.diagnosis.noise_id import identify_noise

            if not data.has_table:
                raise UserError("--noise identify: noise identification needs a log with table angles (it works on "
                                "the residual of a fit over the whole log); on a log without them give the noise: "
                                "a grade, a noise file (calbench noise --out on a table log of the same IMU) or "
                                "NAME=VALUE terms")

            base = model if model is not None else white_fit(data, effects)
            try:
                ident = identify_noise(data, base, known=identification_known(data, held_terms(specs)),
                                       bootstrap=bootstrap)
            except ValueError as e:
                raise UserError(f"--noise identify: {e}") from None
            noise = ident.model
            # what the identification could not do is said with it (a pulse log's default is
            # identified without being asked: the user would not otherwise learn of it)
            held = [sp.strip() for sp in specs if "=" in sp]
            said = [lead + IDENTIFIED + (f", {', '.join(held)} held as given" if held else "")
                    + (f" (note: {ident.white_note})" if ident.white_note else "")]
        elif "=" in s:
            name, v = _term(s)
            try:
                noise = from_terms({name: v}, noise, "given by hand")
            except ValueError as e:
                raise UserError(f"--noise {spec!r}: {e}") from None
            if not any(sp.strip() == "identify" for sp in specs):   # (beside it: held, and said with it)
                said.append(f"{name} = {v:.4g} (SI, given)")
            if TERM_OF_NAME.get(name.split(".")[2]) == "quantization":
                quantized.add(name.split(".")[0])
        elif s.endswith(".json"):
            noise = load_noise_file(s)
            said = [f"from {s}"]
        else:
            raise UserError(f"--noise {spec!r}: expected identify, white, navigation, tactical, a noise .json file "
                            "or NAME=VALUE (e.g. acc.noise.bi=10 ug)")
    if noise is None:
        return None, "; ".join(said), ident
    return with_count_quantization(noise, data, "; ".join(said), quantized) + (ident,)


def with_count_quantization(noise: NoiseModel, data, said: str, named=frozenset()) -> tuple[NoiseModel, str]:
    """(*noise* with a pulse output's quantization — one count's w/√12, from the log's count
    weights — on each of its channels that has none, the sentence *said* saying so). A grade, a
    datasheet's terms or a noise file from an analogue log do not know the counts, and without
    them a rest's block sums were given the white noise alone (the true noise of a helper's 2"
    counts log, given as a file: χ²/dof 6.8; with the counts' quantization, 1.01). The sensors in
    *named* had their quantization named by the user (``gyro.noise.q=…``, 0 included): theirs,
    left as it is."""
    chans, added = list(noise.channels), []
    for s, (sensor, w) in enumerate(zip(("gyro", "acc"), getattr(data, "count_weight", None) or ())):
        if not w or sensor in named or all(chans[3 * s + a].quantization > 0 for a in range(3)):
            continue
        for a in range(3):
            if not chans[3 * s + a].quantization > 0:
                chans[3 * s + a] = replace(chans[3 * s + a], quantization=float(w) / math.sqrt(12.0))
        _, _, unit, scale = TERMS[sensor]["quantization"]
        added.append(f"{sensor} {w / scale:.3g} {unit}/√12")
    if added:
        said += f"; with the counts' quantization from the log's count weights ({', '.join(added)})"
    return replace(noise, channels=tuple(chans), source=said), said


def white_noise_model(data) -> tuple[NoiseModel | None, str]:
    """(white noise model, the sentence saying what it is) of *data*: None — each channel's level
    from its static sample differences, read where it is used — for a log without pulse outputs.
    A pulse output's sample differences are mostly 0 where its counts are coarser than a sample's
    noise, and a white level read from them is one count's w/√12 in every sample; a block of n
    samples would be given n times that variance where its sum carries only the remainders at its
    two ends (benchmarks/coloured_noise_counts_diagnosis.txt: χ²/dof 0.09 and an effect named on
    every log). So on a pulse output the quantization is a term of its own (w/√12 from the count
    weight) and the white level is read from the Allan variance beside it
    (noise_fit.white_beside_quantization)."""
    if data is None or not any(data.count_weight):
        return None, WHITE
    from components.diagnosis.noise_id import ALLAN_SAMPLES
    from components.estimation.allan import first_runs, pooled_allan, static_runs
    from components.estimation.noise_fit import white_beside_quantization, white_ceiling

    use = data.static_usable
    runs = first_runs(static_runs(use), ALLAN_SAMPLES)
    if not runs:
        raise UserError("--noise white: this log of pulse counts has no static run of 8 samples or more, so no "
                        "white level can be read beside the counts' quantization; give the noise (--noise: a grade, "
                        "a noise file or NAME=VALUE terms such as gyro.noise.arw='0.002 deg/sqrt(h)')")
    dt = data.sample_interval
    upto = runs[-1][1]
    q = data.quantization_floor()
    chans, said = [], []
    for s, (sensor, inc) in enumerate((("gyro", data.gyro), ("acc", data.acc))):
        if not q[3 * s]:
            level = data.white_sigma_at_rest(sensor) / np.sqrt(dt)
            chans += [ChannelNoise(white=float(v)) for v in level]
            continue
        taus = []
        for a in range(3):
            av = pooled_allan(np.asarray(inc[:upto, a], float) / dt, runs, dt)
            n, tau = white_beside_quantization(av, float(q[3 * s + a]))
            if not n > 0:
                # no τ rises above the quantization: the most the Allan variance allows, so that
                # σ come out on the wide side, never from a numerical floor (σ up to a hundred
                # times too small on 2" counts); the whole log's block sums read it better
                # (--noise identify, on a log with table angles)
                n = white_ceiling(av)
            chans.append(ChannelNoise(white=n, quantization=float(q[3 * s + a])))
            taus.append(tau)
        read = sorted({f"{t:.3g} s" for t in taus if np.isfinite(t)})
        hidden = sum(not np.isfinite(t) for t in taus)
        parts = ([f"from the Allan variance at τ = {', '.join(read)} beside it"] if read else []) \
            + ([f"below what the counts show on {hidden} axes: the most their Allan variance allows (σ on the "
                "wide side)"] if hidden else [])
        said.append(f"{sensor}: quantization {data.count_weight[s]:.3g}/√12 (its count weight) and white noise "
                    + "; ".join(parts))
    text = "white noise, on the pulse outputs with the counts' quantization as a term of its own (" \
           + "; ".join(said) + ")"
    return NoiseModel(tuple(chans), text), text


def white_fit(data, effects):
    """A calibration of *effects* (default: bias, scale factor, misalignment) under white noise."""
    from components.estimation.lsq import calibrate
    from components.model.effects import DEFAULT_EFFECTS
    from components.model.result import result_from_fit

    eff = list(effects or DEFAULT_EFFECTS)
    return result_from_fit(calibrate(data, eff), eff, data)
