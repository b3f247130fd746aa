"""Where a model fails, as a statistical statement.

The comparison's normalised block residuals z (one per block and channel, N(0, 1) under a
correct model) are grouped into cells — a segment × channel, a condition × channel, a channel —
and each cell is tested on its own: χ² = Σ z² with as many degrees of freedom as blocks,
p = P(χ²_dof > χ²). Looking at hundreds of cells, the largest of them is always well above 1
(the largest of 540 RMS values of pure noise is about 2.5), so a cell is flagged only when its
p-value survives the Holm correction over every cell of its family at α (default 0.01): under
a correct model the chance that anything at all is flagged is at most α per family.

Families: segments × channels, conditions × channels (the conditions overlap each other and the
segments, so they are a family of their own), and the six channels.

The per-cell χ² uses the block count as its dof: with parameters fitted on this log the expected
χ² is a little smaller, which makes the test slightly conservative, never liberal.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from components.estimation.distributions import chi2_sf

CHANNELS = ("gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
ALPHA = 0.01


@dataclass
class Cell:
    family: str          # "segment" | "condition" | "channel"
    name: str            # segment label, condition name, or the channel again
    channel: str
    chi2: float
    dof: int
    p: float
    p_adjusted: float = 1.0
    flagged: bool = False

    @property
    def ratio(self) -> float:
        """RMS of the normalised block residuals in the cell (1 = noise)."""
        return float(np.sqrt(self.chi2 / max(self.dof, 1)))

    def to_json(self) -> dict:
        return {"family": self.family, "name": self.name, "channel": self.channel, "chi2": self.chi2,
                "dof": self.dof, "rms_ratio": self.ratio, "p": self.p, "p_adjusted": self.p_adjusted,
                "flagged": self.flagged}


@dataclass
class Misfits:
    alpha: float
    cells: dict = field(default_factory=dict)   # family -> [Cell]

    def flagged(self, family: str) -> list[Cell]:
        """Flagged cells of *family*, worst (smallest p) first."""
        return sorted((c for c in self.cells.get(family, []) if c.flagged), key=lambda c: (c.p, -c.ratio))

    def looked_at(self, family: str) -> int:
        return len(self.cells.get(family, []))

    def cell(self, family: str, name: str, channel: str) -> Cell | None:
        for c in self.cells.get(family, []):
            if c.name == name and c.channel == channel:
                return c
        return None

    def lines(self) -> list[str]:
        """What a person reads: flagged cells, or that nothing misfits beyond noise."""
        out = []
        for family, what in (("channel", "channel"), ("segment", "segment × channel"),
                             ("condition", "condition × channel")):
            n = self.looked_at(family)
            if not n:
                continue
            bad = self.flagged(family)
            test = f"χ² per cell, Holm over {n} at α = {self.alpha}"
            if not bad:
                out.append(f"no {what} misfits beyond noise ({n} looked at, {test})")
                continue
            shown = ", ".join((c.channel if family == "channel" else f"{c.name} {c.channel}")
                              + f" {c.ratio:.2f}" for c in bad[:8])
            more = f" and {len(bad) - 8} more" if len(bad) > 8 else ""
            out.append(f"{what} misfits beyond noise: {len(bad)} of {n} ({test}; block RMS / noise): "
                       f"{shown}{more}")
        return out

    def to_json(self) -> dict:
        return {"alpha": self.alpha, "test": "chi2 of the normalised block residuals per cell, Holm-corrected "
                                            "over the cells of each family",
                "looked_at": {f: len(c) for f, c in self.cells.items()},
                "flagged": {f: [c.to_json() for c in self.flagged(f)] for f in self.cells},
                "cells": {f: [c.to_json() for c in cs] for f, cs in self.cells.items()}}


def holm(p: np.ndarray) -> np.ndarray:
    """Holm step-down adjusted p-values (family-wise error control under any dependence)."""
    p = np.asarray(p, dtype=float)
    m = len(p)
    if m == 0:
        return p
    order = np.argsort(p, kind="stable")
    adj = np.minimum(1.0, (m - np.arange(m)) * p[order])
    adj = np.maximum.accumulate(adj)
    out = np.empty(m)
    out[order] = adj
    return out


def _cells(family: str, groups: dict, z: np.ndarray, channel: np.ndarray) -> list[Cell]:
    out = []
    for name, sel in groups.items():
        for k, ch in enumerate(CHANNELS):
            m = sel & (channel == k)
            n = int(np.count_nonzero(m))
            if n == 0:
                continue
            chi2 = float(np.sum(z[m] ** 2))
            out.append(Cell(family, name, ch, chi2, n, float(chi2_sf(chi2, n))))
    return out


def misfits(rows: dict, segment_of_row: np.ndarray | None, conditions: dict, alpha: float = ALPHA) -> Misfits:
    """Test every cell of the block rows (``rows`` of a comparison: z, channel). ``segment_of_row``:
    the segment label of each row (None: no segments); ``conditions``: name -> row mask."""
    z = np.asarray(rows["z"], dtype=float)
    ch = np.asarray(rows["channel"])
    res = Misfits(alpha)
    fams = {"channel": {c: np.ones(len(z), bool) for c in ["all"]}}
    res.cells["channel"] = _cells("channel", fams["channel"], z, ch)
    for c in res.cells["channel"]:
        c.name = c.channel
    if segment_of_row is not None:
        labels = np.asarray(segment_of_row).astype(str)
        res.cells["segment"] = _cells("segment", {s: labels == s for s in dict.fromkeys(labels)}, z, ch)
    if conditions:
        res.cells["condition"] = _cells("condition", conditions, z, ch)
    for cells in res.cells.values():
        adj = holm(np.array([c.p for c in cells]))
        for c, a in zip(cells, adj):
            c.p_adjusted = float(a)
            c.flagged = bool(a < alpha)
    return res


def chi2_band(dof: int) -> tuple[float, float]:
    """The 99.9 % band of χ²/dof for a correct model with *dof* degrees of freedom."""
    from components.estimation.distributions import chi2_isf

    n = max(int(dof), 1)
    return chi2_isf(0.9995, n) / n, chi2_isf(0.0005, n) / n


def chi2_band_note(chi2_per_dof: float, dof: int, above: bool = False) -> str | None:
    """The sentence for a χ²/dof outside its 99.9 % band, or None. Below it the noise model
    states more noise than the residual has (every σ too wide: a noise file of another log or
    IMU, a grade too noisy); above it (said only when *above*: compare and diagnose show where)
    the model or the noise model lacks something."""
    low, high = chi2_band(dof)
    if chi2_per_dof < low:
        return (f"chi2/dof {chi2_per_dof:.3f} is below what a correct model gives (99.9 % band from {low:.3f}): the "
                "noise model states more noise than the residual has, so every σ from it is too wide; identify the "
                "noise on this log (calbench noise, --noise identify) or check the noise given")
    if above and chi2_per_dof > high:
        return (f"chi2/dof {chi2_per_dof:.3f} is above what a correct model gives (99.9 % band up to {high:.3f}): the "
                "model or its noise model lacks something, and the σ are too small; calbench compare shows where, "
                "calbench diagnose which effect or noise term")
    return None
