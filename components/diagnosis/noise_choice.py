"""Which noise model an estimate, a comparison or a diagnosis uses, from what the user said —
never a silent guess: the choice comes back with a sentence saying what was assumed.

Specifications, applied in order (``--noise`` on the command line, repeatable):

- ``identify``: identified on this log (components.diagnosis.noise_id), around the given model
  or, without one, around a white-noise fit of the default effects;
- ``navigation`` / ``tactical``: a typical grade's noise (components.model.noise.grade);
- a ``.json`` file: a noise file (``calbench-noise/1``, written by ``calbench noise --out``) or a
  calibration result holding a composite model;
- ``NAME=VALUE``: one term by hand, on top of what came before, e.g. ``acc.noise.bi=10 ug``,
  ``gyro.noise.arw=0.002 deg/sqrt(h)``, ``acc.noise.q.x=1e-5`` (SI without a unit);
- ``white``: white noise, its level from the data's sample-to-sample differences.

Without any: a model's own composite noise if it has one; a log of pulse counts gets its
quantization from the count weights and the rest identified from the static runs (its sample
differences are mostly zero, so no white level can be read from them); otherwise white noise
as ``white`` above.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from components.errors import UserError
from components.model.noise import CHANNELS, FORMAT, NoiseModel, from_terms, grade
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
    try:
        v = quantity(float(value) if _is_float(value) else value, name, "--noise", units, si)
    except QuantityError as e:
        raise UserError(str(e)) from None
    if not (v >= 0 and math.isfinite(v)):
        raise UserError(f"--noise {spec!r}: expected a magnitude >= 0")
    return name, v


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def load_noise_file(path: str | Path) -> NoiseModel:
    """A noise model from a noise file or from a result file's composite block."""
    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except (OSError, ValueError) as e:
        raise UserError(f"--noise {p}: cannot read a JSON noise file ({e})") from None
    if isinstance(d, dict) and d.get("format") == FORMAT:
        return NoiseModel.from_dict(d)
    if isinstance(d, dict) and isinstance(d.get("noise"), dict) and "composite" in d["noise"]:
        return NoiseModel.from_dict(d["noise"]["composite"])
    raise UserError(f"--noise {p}: expected a noise file (format {FORMAT!r}, from `calbench noise --out`) or a "
                    "calibration result with a composite noise model")


def quantization_known(data) -> dict:
    """Per channel, the quantization of a pulse output from its count weight (w / √12)."""
    out = {}
    for s, w in enumerate(data.count_weight):
        if w:
            for a in range(3):
                out[3 * s + a] = {"quantization": float(w) / math.sqrt(12.0)}
    return out


def choose_noise(specs: list[str] | None, data, model=None, effects=None, *, bootstrap: int = 30,
                 base: NoiseModel | None = None):
    """(noise model or None for white, the sentence saying what it is, the identification if one
    ran) for *data*, given the user's *specs*, the calibrated *model* if any, and the *effects*
    a model would be fitted with; *base*: the model the specifications start from."""
    specs = list(specs or [])
    ident = None
    if not specs:
        if model is not None and model.noise_model() is not None:
            return model.noise_model(), f"the model's own: {model.noise_model().source}", None
        if data is not None and getattr(data, "noise", None):
            own = NoiseModel.from_dict(data.noise)
            return NoiseModel(own.channels, "the log's own (imu.noise)", own.sigmas), "the log's own (imu.noise)", None
        if any(data.count_weight) and data.has_table:
            specs = ["identify"]
            lead = "pulse counts: quantization from the count weights, the rest "
        else:
            return None, WHITE, None
    else:
        lead = ""
    noise: NoiseModel | None = base
    said = [base.source] if base is not None else []
    for spec in specs:
        s = spec.strip()
        if s == "white":
            noise = None
            said.append(WHITE + _quantization_warning(data))
        elif s in ("navigation", "tactical"):
            noise = grade(s)
            said.append(f"{s} grade (given)")
        elif s == "identify":
            from components.diagnosis.noise_id import identify_noise

            if not data.has_table:
                raise UserError("--noise identify: noise identification needs a log with table angles (it works on "
                                "the residual of a fit over the whole log); on a log without them give the noise: "
                                "a grade, a noise file (calbench noise --out on a table log of the same IMU) or "
                                "NAME=VALUE terms")

            base = model if model is not None else white_fit(data, effects)
            try:
                ident = identify_noise(data, base, known=quantization_known(data), bootstrap=bootstrap)
            except ValueError as e:
                raise UserError(f"--noise identify: {e}") from None
            noise = ident.model
            said.append(lead + "identified on this log")
        elif "=" in s:
            name, v = _term(s)
            noise = from_terms({name: v}, noise, "given by hand")
            said.append(f"{name} = {v:.4g} (SI, given)")
        elif s.endswith(".json"):
            noise = load_noise_file(s)
            said.append(f"from {s}")
        else:
            raise UserError(f"--noise {spec!r}: expected identify, white, navigation, tactical, a noise .json file "
                            "or NAME=VALUE (e.g. acc.noise.bi=10 ug)")
    if noise is not None:
        noise = NoiseModel(noise.channels, "; ".join(said), noise.sigmas)
    return noise, "; ".join(said), ident


def _quantization_warning(data) -> str:
    """What `white` gets wrong on pulse counts coarser than the white noise: their sample
    differences are mostly 0, so the level is the floor a count leaves in one sample (w/√12),
    and a block of n samples is given n times that variance where its sum carries only the
    remainders at its two ends (benchmarks/coloured_noise_counts_diagnosis.txt: χ²/dof 0.09 and
    an effect named on every log). Empty when no channel's level is that floor."""
    if data is None or not any(data.count_weight):
        return ""
    from components.estimation.blocks import white_noise_sigma

    use = data.static & data.usable
    floor = data.quantization_floor()
    raw = np.concatenate([white_noise_sigma(data.gyro, use), white_noise_sigma(data.acc, use)])
    binds = [CHANNELS[k] for k in range(6) if floor[k] > 0 and not raw[k] > floor[k]]
    if not binds:
        return ""
    return (f" — but on {', '.join(binds)} the counts are coarser than the noise: the level is one count's "
            "w/√12 in every sample, which overstates a block sum's quantization (only its two end remainders "
            "count), so χ² and the tests come out far too small; --noise identify models the quantization")


def white_fit(data, effects):
    """A calibration of *effects* (default: bias, scale factor, misalignment) under white noise."""
    from components.estimation.lsq import calibrate
    from components.model.effects import DEFAULT_EFFECTS
    from components.model.result import result_from_fit

    eff = list(effects or DEFAULT_EFFECTS)
    return result_from_fit(calibrate(data, eff), eff, data)
