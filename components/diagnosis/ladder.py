"""The ladder: one line per model version (baseline, + an effect, + another ...) with its χ²/dof
and RMS against the noise floor per channel, so a user sees the error fall as effects are added."""
from __future__ import annotations


def ladder_entry(comparison, effects: list[str], label: str | None = None) -> dict:
    """One rung from a :class:`~components.diagnosis.compare.Comparison` of the model with *effects*."""
    ch = comparison.channels
    return {"model": label or "+".join(effects), "effects": list(effects),
            "chi2_per_dof": comparison.chi2_per_dof,
            "rms": {k: v["rms"] for k, v in ch.items()},
            "noise_floor": {k: v["noise_floor"] for k, v in ch.items()},
            # what χ²/dof was taken under: a rung made before the noise was identified again with
            # the new effect had another noise model than the rungs after it
            "noise": comparison.noise_terms or "white noise"}


def ladder_lines(ladder: list[dict]) -> list[str]:
    """The ladder as a table: model, χ²/dof, RMS / noise floor per channel."""
    lines = [f"{'model':48s} {'chi2/dof':>9s}  rms/noise: gyro x y z, acc x y z"]
    for e in ladder:
        ratios = " ".join(f"{e['rms'][k] / e['noise_floor'][k]:5.2f}" for k in e["rms"])
        lines.append(f"{e['model'][:48]:48s} {e['chi2_per_dof']:9.3f}  {ratios}")
    noises = [e.get("noise") for e in ladder]
    if len(set(noises)) > 1:
        # (a ladder written before the rungs said their noise has none: said as unknown)
        lines += [f"  {e['model'][:46]}: chi2/dof under {e.get('noise') or 'a noise model not recorded'}" for e in ladder]
    return lines
