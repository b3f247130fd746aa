"""The noise of an IMU channel as a composite of the IEEE Std 952 / 1554 terms, and the model of
six channels (its file form, terms by hand, a grade).

Per channel (gyro x, y, z; accelerometer x, y, z), in SI and rate units (rad/s, m/s²):

| term | symbol | unit (gyro / acc) | Allan variance at τ |
|---|---|---|---|
| quantization | Q | rad / m/s | 3 Q² / τ² |
| white noise (ARW / VRW) | N | rad/√s / m/s/√s | N² / τ |
| bias instability (flicker floor) | B | rad/s / m/s² | (2 ln 2 / π) B² |
| rate / acceleration random walk | K | rad/s/√s / m/s²/√s | K² τ / 3 |
| Gauss–Markov (σ, T) | | rad/s / m/s², s | σ² g(τ/T) |

A linear drift is not noise here: it is the effect ``*.drift`` of the vocabulary.

Its exact discrete form on the estimators' observation blocks is components.model.block_noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from components.model.effects import DEG, DEG_H, UG
from components.model.flicker import FLICKER_AVAR, flicker_terms, gm_avar

# a noise level read within this many of its σ of 0 is not measured (as a term's presence test)
READ_SIGMAS = 3.0
CHANNELS = ("gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
AXES = "xyz"
# term -> (name in the vocabulary per sensor, SI unit, display unit, SI per display unit)
TERMS = {
    "gyro": {"quantization": ("gyro.noise.q", "rad", "arcsec", DEG / 3600),
             "white": ("gyro.noise.arw", "rad/sqrt(s)", "deg/sqrt(h)", DEG / 60),
             "bias_instability": ("gyro.noise.bi", "rad/s", "deg/h", DEG_H),
             "random_walk": ("gyro.noise.rrw", "rad/s/sqrt(s)", "deg/h/sqrt(h)", DEG_H / 60)},
    "acc": {"quantization": ("acc.noise.q", "m/s", "mm/s", 1e-3),
            "white": ("acc.noise.vrw", "m/s/sqrt(s)", "ug/sqrt(Hz)", UG),
            "bias_instability": ("acc.noise.bi", "m/s2", "ug", UG),
            "random_walk": ("acc.noise.rrw", "m/s2/sqrt(s)", "ug/sqrt(h)", UG / 60)},
}
GM_UNITS = {"gyro": ("rad/s", "deg/h", DEG_H), "acc": ("m/s2", "ug", UG)}
FORMAT = "calbench-noise/1"


def sensor_of(channel: int) -> str:
    return "gyro" if channel < 3 else "acc"


def sensor_term_name(channel: int, term: str) -> str:
    """The vocabulary name of *term* for *channel*'s sensor, all three axes: ``acc.noise.rrw``."""
    return TERMS[sensor_of(channel)][term][0]


def term_name(channel: int, term: str) -> str:
    """The vocabulary name of *term* on *channel* (0-5): ``gyro.noise.arw.x``, ``acc.noise.bi.z``."""
    return f"{sensor_term_name(channel, term)}.{AXES[channel % 3]}"


@dataclass(frozen=True)
class ChannelNoise:
    """The composite noise of one channel (SI, rate units; see the module docstring)."""

    white: float = 0.0
    quantization: float = 0.0
    bias_instability: float = 0.0
    random_walk: float = 0.0
    gauss_markov: tuple = ()          # ((σ, T), ...)
    flicker_range: tuple | None = None  # (T_lo, T_hi) of the bias instability; None: the log's;
    #                                     T_hi None: up to the log's duration

    @property
    def coloured(self) -> bool:
        """Anything but white noise: the block sums are correlated (or, for quantization, their
        variance is not the white one)."""
        return bool(self.quantization or self.bias_instability or self.random_walk or self.gauss_markov)

    def avar(self, tau) -> np.ndarray:
        """Allan variance at averaging times *tau* [s] (the flicker floor taken flat)."""
        tau = np.asarray(tau, float)
        a = 3 * self.quantization**2 / tau**2 + self.white**2 / tau + FLICKER_AVAR * self.bias_instability**2 \
            + self.random_walk**2 * tau / 3
        for s, T in self.gauss_markov:
            a = a + gm_avar(s, T, tau)
        return a

    def avar_realised(self, tau) -> np.ndarray:
        """Allan variance at *tau* of the model as realised: a flicker floor with a stated range
        as its Gauss–Markov sum (below its lowest time constant it falls away, where
        :meth:`avar` keeps it flat; the two agree inside the range). What a plot of the model
        beside the measured deviation shows."""
        tau = np.asarray(tau, float)
        if not (self.bias_instability and self.flicker_range):
            return self.avar(tau)
        flat = replace(self, bias_instability=0.0)
        lo, hi = self.flicker_range
        lo = float(np.min(tau)) if lo is None else lo
        terms = flicker_terms(self.bias_instability, lo, max(float(np.max(tau)), 2 * lo) if hi is None else hi)
        return flat.avar(tau) + sum((gm_avar(s, T, tau) for s, T in terms), np.zeros_like(tau))

    def gm_terms(self, t_lo: float, t_hi: float) -> list[tuple[float, float]]:
        """Every Gauss–Markov term: the explicit ones and the flicker floor realised over its own
        range or, without one, over [t_lo, t_hi] (the time scales a log can show)."""
        out = [(float(s), float(T)) for s, T in self.gauss_markov if s > 0]
        if self.bias_instability > 0:
            lo, hi = self.flicker_range or (t_lo, t_hi)
            lo = t_lo if lo is None else lo
            hi = max(t_hi, 2 * lo) if hi is None else hi
            out += flicker_terms(self.bias_instability, lo, hi)
        return out


@dataclass(frozen=True)
class NoiseModel:
    """Six channels' noise, and how it was obtained (``source``) with a σ per identified term and,
    for the slow terms identified by likelihood, their profile-likelihood interval (``intervals``:
    the magnitudes where the deviance reaches 9, three σ of a one-parameter interval; on short
    logs far from the symmetric value ± 3σ)."""

    channels: tuple
    source: str = ""
    sigmas: dict = field(default_factory=dict)
    intervals: dict = field(default_factory=dict)

    @property
    def coloured(self) -> bool:
        return any(c.coloured for c in self.channels)

    @classmethod
    def white(cls, sigma_per_sample, dt: float, source: str = "white noise") -> "NoiseModel":
        """White noise only, from a per-sample σ of the increments (6,) and the sample interval."""
        s = np.broadcast_to(np.asarray(sigma_per_sample, float), (6,))
        return cls(tuple(ChannelNoise(white=float(x) / math.sqrt(dt)) for x in s), source)

    @classmethod
    def per_sensor(cls, gyro: dict | None = None, acc: dict | None = None, source: str = "given") -> "NoiseModel":
        """The same terms on the three axes of a sensor: ``{"white": N, "bias_instability": B, ...}``."""
        g, a = ChannelNoise(**(gyro or {})), ChannelNoise(**(acc or {}))
        return cls((g, g, g, a, a, a), source)

    def white_sigma(self, dt: float) -> np.ndarray:
        """Per-sample white σ of the increments (6,)."""
        return np.array([c.white for c in self.channels]) * math.sqrt(dt)

    def white_poorly_read(self) -> list[str]:
        """The channels (CHANNELS names) whose white level the identification read below
        :data:`READ_SIGMAS` of its σ, or bounded from above only (its interval from 0). Such a level
        is kept (every sensor has white noise) but the log did not measure it: beside a pulse
        output's quantization a level read low weighs the channel's block sums too much (the
        foreign rig's 2" gyros, read at 0.34-0.71 of the truth, 1.1-3.1 of their σ from 0: χ²/dof 1.24
        with nothing said). A level given by hand has no σ and is never named."""
        out = []
        for k, (name, ch) in enumerate(zip(CHANNELS, self.channels)):
            pname = term_name(k, "white")
            sig = float(self.sigmas.get(pname, math.nan))
            below = ch.white > 0 and math.isfinite(sig) and ch.white < READ_SIGMAS * sig
            interval = self.intervals.get(pname)
            if below or (ch.white > 0 and interval is not None and not interval[0] > 0):
                out.append(name)
        return out

    def with_channel(self, k: int, ch: ChannelNoise) -> "NoiseModel":
        chans = list(self.channels)
        chans[k] = ch
        return replace(self, channels=tuple(chans))

    # ------------------------------------------------------------------ file form
    def to_dict(self) -> dict:
        """The result file's ``noise`` block: per channel the terms present, SI value, unit and the
        readable value; σ of identified terms."""
        out = {"format": FORMAT, "source": self.source, "channels": {}}
        for k, (name, ch) in enumerate(zip(CHANNELS, self.channels)):
            sensor = sensor_of(k)
            d = {}
            for term, (vname, unit, dunit, scale) in TERMS[sensor].items():
                v = getattr(ch, term)
                if v:
                    pname = f"{vname}.{AXES[k % 3]}"
                    d[term] = {"value": v, "unit": unit, "display": [v / scale, dunit]}
                    if pname in self.sigmas:
                        # a term fixed rather than estimated (a count weight's quantization) has
                        # no σ: null, as JSON has no NaN
                        sig = float(self.sigmas[pname])
                        d[term]["sigma"] = sig if math.isfinite(sig) else None
                    if pname in self.intervals:
                        # an end the log does not bound is null (JSON has no infinity)
                        d[term]["interval_3sigma"] = [float(x) if math.isfinite(x) and x > 0 else None
                                                      for x in self.intervals[pname]]
            if ch.gauss_markov:
                gu, gd, gs = GM_UNITS[sensor]
                d["gauss_markov"] = [{"sigma": s, "tau_s": T, "unit": gu, "display": [s / gs, gd]}
                                     for s, T in ch.gauss_markov]
            if ch.flicker_range and ch.bias_instability:
                d["flicker_range_s"] = list(ch.flicker_range)
            out["channels"][name] = d
        return out

    @classmethod
    def from_dict(cls, d: dict) -> "NoiseModel":
        """The model of a noise block (:meth:`to_dict`'s form). Every channel must be there (one
        without noise is ``{}``), every key known, every value a finite magnitude in the term's
        SI unit: a ValueError naming the key otherwise (a typing mistake must not leave a channel
        silently white)."""
        if not isinstance(d, dict) or not isinstance(d.get("channels"), dict):
            raise ValueError("expected an object with 'channels': {gyro_x: {...}, ..., acc_z: {...}}")
        given = d["channels"]
        unknown = [k for k in given if k not in CHANNELS]
        if unknown:
            raise ValueError(f"channels: unknown channel {unknown[0]!r}; expected {', '.join(CHANNELS)}")
        missing = [k for k in CHANNELS if k not in given]
        if missing:
            raise ValueError(f"channels: {', '.join(missing)} missing; a noise model names all six channels (one "
                             "without noise as {})")
        chans, sig, iv = [], {}, {}
        for k, name in enumerate(CHANNELS):
            c = given[name]
            where = f"channels.{name}"
            if not isinstance(c, dict):
                raise ValueError(f"{where}: expected an object of terms, got {type(c).__name__}")
            terms = TERMS[sensor_of(k)]
            extra = [t for t in c if t not in terms and t not in ("gauss_markov", "flicker_range_s")]
            if extra:
                raise ValueError(f"{where}: unknown term {extra[0]!r}; expected {', '.join(terms)}, gauss_markov, "
                                 "flicker_range_s")
            kw = {}
            for term, (vname, unit, *_rest) in terms.items():
                if term not in c:
                    continue
                entry = c[term]
                at = f"{where}.{term}"
                if not isinstance(entry, dict):
                    raise ValueError(f"{at}: expected {{\"value\": ..., \"unit\": \"{unit}\"}}")
                if entry.get("unit", unit) != unit:
                    raise ValueError(f"{at}: unit {entry.get('unit')!r}; expected {unit!r} (noise files are in SI)")
                kw[term] = _magnitude(entry.get("value"), f"{at}.value")
                pname = f"{vname}.{AXES[k % 3]}"
                sigma = entry.get("sigma")
                # (files before null was written for a fixed term's σ hold NaN there)
                if sigma is not None and not (isinstance(sigma, float) and math.isnan(sigma)):
                    sig[pname] = _magnitude(sigma, f"{at}.sigma")
                if entry.get("interval_3sigma") is not None:
                    b = entry["interval_3sigma"]
                    if not (isinstance(b, list) and len(b) == 2):
                        raise ValueError(f"{at}.interval_3sigma: expected [low, high] (null: unbounded)")
                    lo = 0.0 if b[0] is None else _magnitude(b[0], f"{at}.interval_3sigma")
                    iv[pname] = (lo, math.inf if b[1] is None else _magnitude(b[1], f"{at}.interval_3sigma"))
            gm = c.get("gauss_markov", [])
            if not isinstance(gm, list) or not all(isinstance(g, dict) for g in gm):
                raise ValueError(f"{where}.gauss_markov: expected a list of {{\"sigma\": ..., \"tau_s\": ...}}")
            pairs = []
            for j, g in enumerate(gm):
                T = _magnitude(g.get("tau_s"), f"{where}.gauss_markov[{j}].tau_s")
                if T <= 0:
                    raise ValueError(f"{where}.gauss_markov[{j}].tau_s: expected a time constant > 0 s")
                pairs.append((_magnitude(g.get("sigma"), f"{where}.gauss_markov[{j}].sigma"), T))
            fr = c.get("flicker_range_s")
            if fr is not None:
                if not (isinstance(fr, list) and len(fr) == 2):
                    raise ValueError(f"{where}.flicker_range_s: expected [lowest, highest] time constant [s]")
                lo = None if fr[0] is None else _magnitude(fr[0], f"{where}.flicker_range_s")
                hi = None if fr[1] is None else _magnitude(fr[1], f"{where}.flicker_range_s")
                if (lo is not None and lo <= 0) or (None not in (lo, hi) and hi <= lo):
                    raise ValueError(f"{where}.flicker_range_s: {fr}; expected 0 < lowest < highest")
                fr = (lo, hi)
            chans.append(ChannelNoise(gauss_markov=tuple(pairs), flicker_range=fr, **kw))
        return cls(tuple(chans), str(d.get("source", "")), sig, iv)


def _magnitude(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
        raise ValueError(f"{where}: {v!r}; expected a finite number >= 0")
    return float(v)


def describe(noise: NoiseModel | None) -> str:
    """One line: each sensor's terms in readable units; each axis's where the axes differ (one
    axis's identified floor against the others' is what tells an effect taken for noise)."""
    if noise is None:
        return "white noise"

    def terms(sensor: str, ch: ChannelNoise) -> str:
        items = []
        for term, (vname, _, dunit, scale) in TERMS[sensor].items():
            v = getattr(ch, term)
            if v:
                items.append(f"{vname.split('.')[-1]} {v / scale:.3g} {dunit}")
        for s, T in ch.gauss_markov:
            items.append(f"GM {s / GM_UNITS[sensor][2]:.3g} {GM_UNITS[sensor][1]} ({T:.3g} s)")
        return ", ".join(items) or "none"

    parts = []
    for sensor, off in (("gyro", 0), ("acc", 3)):
        axes = noise.channels[off:off + 3]
        if all(c == axes[0] for c in axes):
            parts.append(f"{sensor} {terms(sensor, axes[0])}")
        else:
            parts.append(f"{sensor} " + " / ".join(f"{a}: {terms(sensor, c)}" for a, c in zip("xyz", axes)))
    return "; ".join(parts)


# FMU noise parameter / --noise name -> ChannelNoise field
TERM_OF_NAME = {"arw": "white", "vrw": "white", "q": "quantization", "bi": "bias_instability",
                "rrw": "random_walk"}
# --noise name -> the end of the bias instability's flicker range it sets (time constants [s])
RANGE_OF_NAME = {"bi_tau_min": 0, "bi_tau_max": 1}


def from_terms(terms: dict, base: NoiseModel | None = None, source: str = "given") -> NoiseModel:
    """A model from named terms in SI, ``{"gyro.noise.arw": N, "acc.noise.bi.y": B, ...}`` (a name
    without an axis sets all three), on top of *base* (default: no noise). ``bi_tau_min`` and
    ``bi_tau_max`` [s] bound the bias instability's flicker range (unbounded: the log's). The σ
    and profile intervals *base* has for terms not set here stay (an identified term keeps what
    says it was identified; one given by hand has none)."""
    chans = list(base.channels) if base is not None else [ChannelNoise()] * 6
    sigmas = dict(base.sigmas) if base is not None else {}
    intervals = dict(base.intervals) if base is not None else {}
    for name, v in terms.items():
        parts = name.split(".")
        if len(parts) not in (3, 4) or parts[0] not in ("gyro", "acc") or parts[1] != "noise" \
                or parts[2] not in (*TERM_OF_NAME, *RANGE_OF_NAME) or (len(parts) == 4 and parts[3] not in AXES):
            raise ValueError(f"noise term {name!r}: expected <gyro|acc>.noise.<arw|vrw|q|bi|rrw|bi_tau_min|"
                             "bi_tau_max>[.x|.y|.z]")
        if (parts[0] == "gyro") != (parts[2] != "vrw") and parts[2] in ("arw", "vrw"):
            raise ValueError(f"noise term {name!r}: the gyro's white noise is 'arw', the accelerometer's 'vrw'")
        off = 0 if parts[0] == "gyro" else 3
        axes = [AXES.index(parts[3])] if len(parts) == 4 else [0, 1, 2]
        for a in axes:
            ch = chans[off + a]
            if parts[2] in RANGE_OF_NAME:
                rng = list(ch.flicker_range or (None, None))
                rng[RANGE_OF_NAME[parts[2]]] = float(v)
                if (rng[0] is not None and rng[0] <= 0) or (None not in rng and rng[1] <= rng[0]):
                    raise ValueError(f"noise term {name!r}: the flicker range {rng[0]}-{rng[1]} s; expected "
                                     "0 < bi_tau_min < bi_tau_max")
                chans[off + a] = replace(ch, flicker_range=tuple(rng))
            else:
                chans[off + a] = replace(ch, **{TERM_OF_NAME[parts[2]]: float(v)})
                set_here = term_name(off + a, TERM_OF_NAME[parts[2]])
                sigmas.pop(set_here, None)
                intervals.pop(set_here, None)
    return NoiseModel(tuple(chans), source, sigmas, intervals)


def from_fmu_parameters(noise: dict, gyro_count: float | None = None, acc_count: float | None = None,
                        source: str = "injected") -> NoiseModel:
    """The model of what the IMU FMU simulates from its noise parameters (SI, the scenario's
    ``[imu.noise]`` names): white ``*.noise.arw|vrw``; bias instability ``*.noise.bi`` as one
    Gauss–Markov term of correlation time ``bi_tau`` (σ = B · 0.664282 / 0.617364, its ADEV peak
    at the flicker floor), or, with ``bi_tau_max`` > ``bi_tau``, the flicker floor realised
    between them; random walk ``*.noise.rrw``; quantization of a pulse output of count weight
    w: Q = w / √12."""
    chans = []
    for sensor, white, count in (("gyro", "arw", gyro_count), ("acc", "vrw", acc_count)):
        B = float(noise.get(f"{sensor}.noise.bi", 0.0))
        tau = float(noise.get(f"{sensor}.noise.bi_tau", 100.0))
        tau_max = float(noise.get(f"{sensor}.noise.bi_tau_max", 0.0))
        kw = {"white": float(noise.get(f"{sensor}.noise.{white}", 0.0)),
              "random_walk": float(noise.get(f"{sensor}.noise.rrw", 0.0)),
              "quantization": float(count) / math.sqrt(12.0) if count else 0.0}
        if B > 0 and tau_max > tau:
            kw.update(bias_instability=B, flicker_range=(tau, tau_max))
        elif B > 0:
            kw["gauss_markov"] = ((B * 0.664282 / 0.617364, tau),)
        chans += [ChannelNoise(**kw)] * 3
    return NoiseModel(tuple(chans), source)


def grade(name: str) -> NoiseModel:
    """The noise of a typical IMU grade (a navigation-grade ring-laser or fibre-optic gyro with
    servo accelerometers; tactical grade 100 times noisier): white noise, bias instability and
    random walk on every axis."""
    k = {"navigation": 1.0, "tactical": 100.0}[name]
    gyro = {"white": k * 0.002 * DEG / 60, "bias_instability": k * 0.003 * DEG_H,
            "random_walk": k * 0.0003 * DEG_H / 60}
    acc = {"white": k * 10 * UG, "bias_instability": k * 10 * UG, "random_walk": k * 1 * UG / 60}
    return NoiseModel.per_sensor(gyro, acc, source=f"{name} grade")
