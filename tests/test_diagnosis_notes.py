"""The diagnosis never shows a nonsense number as an estimate and never contradicts itself
(components.diagnosis.candidate_notes). On the spec's example log with a model that lacks the
scale factors and misalignments (so many candidates are significant, one of them fitted beyond
its plausible limit): every candidate with p < α that is not the verdict carries a status and
the reason, the verdict lines name it, an implausible candidate's value is not printed, and two
candidates that cannot be told apart get advice that names what each one needs."""
from __future__ import annotations

import pytest

from components.cli import main
from components.diagnosis.candidate_notes import (
    SEPARATE,
    candidate_notes_lines,
    ranking_line,
    separation_advice,
    verdict_lines,
)
from components.diagnosis.diagnose import diagnose
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import EFFECTS, effect_of
from components.model.excitation import needs
from components.model.plausibility import plausible_limit
from components.model.result import result_from_fit


@pytest.fixture(scope="module")
def incomplete(conformance, tmp_path_factory):
    """The example log, a model with biases only, its diagnosis, and the model file."""
    log = read_log(conformance / "example")
    data = LogData.from_log(log)
    effects = ["gyro.bias", "acc.bias"]
    model = result_from_fit(calibrate(data, effects), effects, data, log)
    path = tmp_path_factory.mktemp("notes") / "bias.json"
    model.save(path)
    return diagnose(data, model, forward=True), path


def test_every_significant_candidate_that_is_not_the_verdict_says_why(incomplete):
    d, _ = incomplete
    significant = [c for c in d.ranking if c.p_adjusted < d.alpha]
    assert len(significant) > 3  # the control: this model lacks a lot
    text = "\n".join(verdict_lines(d))
    for c in significant:
        assert c.status and c.status != "not significant", (c.effect, c.status)
        if c.status != "verdict":
            assert c.why, c.effect
            assert c.effect in text, (c.effect, text)


def test_implausible_candidates_are_beyond_their_limit_and_show_no_value(incomplete):
    d, _ = incomplete
    bad = [c for c in d.ranking if c.status == "implausible"]
    assert bad, "the example with biases only has a candidate fitted beyond its plausible limit"
    for c in bad:
        p = c.implausible[0]
        value = c.parameters[p][0]
        # independent of the notes: beyond what any real IMU has, or 1e5 × the navigation-grade value
        assert abs(value) > min(plausible_limit(p), 1e5 * EFFECTS[c.effect].typical)
        line = ranking_line(1, c)
        assert "not an estimate" in line and f"{value:+.4g}" not in line
        assert any(n.startswith("implausible: ") and "limit" in n for n in candidate_notes_lines(c))
    # what could be an estimate is ranked above what cannot
    kinds = [c.status in ("implausible", "unidentifiable") for c in d.ranking]
    assert kinds == sorted(kinds)


def test_indistinguishable_pairs_get_advice_that_separates_them(incomplete):
    d, _ = incomplete
    pairs = [(c, o, advice) for c in d.ranking for o, _, advice in c.indistinguishable]
    assert pairs
    for c, other, advice in pairs:
        if frozenset({c.effect, other}) in SEPARATE:
            continue
        o = next(x for x in d.ranking if x.effect == other)
        na, nb = needs(c.signature["parameter"]), needs(o.signature["parameter"])
        if na != nb:
            assert na in advice and nb in advice, advice
    # the generic advice is not the same sentence for both effects' parameters
    a = separation_advice("gyro.gsens", "acc.lever", "gyro.gsens.xy", "acc.lever.x.x")
    assert needs("gyro.gsens.xy") in a and needs("acc.lever.x.x") in a


def test_console_shows_statuses_not_nonsense(incomplete, conformance, capsys):
    d, path = incomplete
    assert main(["diagnose", str(conformance / "example"), "--model", str(path), "--top", "40"]) == 0
    out = capsys.readouterr().out
    for c in d.ranking[:40]:
        if c.status == "implausible":
            p = c.implausible[0]
            unit, scale = effect_of(p).display
            assert f"{p} = {c.parameters[p][0] / scale:+.4g}" not in out
            assert "implausible: " in out
    assert "other candidate(s) with p < α" in out or all(
        c.status == "verdict" for c in d.ranking if c.p_adjusted < d.alpha)


def test_effects_ranked_before_a_noise_term_are_said_to_need_ranking_again(incomplete):
    """A forward selection that names an effect and then a noise term made the effect's pick under
    the noise model it then found too simple: the verdict says so and how to rank again; a
    selection of effects alone (the example's) does not."""
    import dataclasses

    d, _ = incomplete
    assert not any("ranked under a noise model" in line for line in verdict_lines(d))
    late = dataclasses.replace(d, found=d.found[:1] + ["acc.noise.bi"],
                               steps=d.steps[:1] + [{"noise_term": "acc.noise.bi", "chi2_per_dof_before": 1.5,
                                                     "chi2_per_dof_after": 1.0, "loglik_gain": 600.0}])
    said = [line for line in verdict_lines(late) if "ranked under a noise model" in line]
    assert len(said) == 1 and "acc.noise.bi found after them" in said[0] and "--noise identify" in said[0]


def test_the_candidates_below_the_top_are_named(incomplete, conformance, capsys):
    """diagnose prints --top ranking lines; the rest were left off without a word (a table effect
    among them was invisible): they are named in one line, with whether any is significant."""
    d, path = incomplete
    capsys.readouterr()
    assert main(["diagnose", str(conformance / "example"), "--model", str(path), "--top", "3"]) in (0, 1)
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if "more below" in x)
    assert f"{len(d.ranking) - 3} more below" in line and f"--top {len(d.ranking)}" in line
    assert all(c.effect in line for c in d.ranking[3:])


def test_effects_named_in_turn_are_not_also_listed_as_not_the_verdict(incomplete):
    """"in turn: gyro.sf_asym, acc.k2" then "not the verdict: also significant: acc.k2" said two
    things of one effect: the ones found in turn are named once."""
    d, _ = incomplete
    assert len(d.found) > 1
    lines = verdict_lines(d)
    other = next((x for x in lines if "are not the verdict" in x), "")
    import re

    listed = set(re.findall(r"\b[a-z0-9]+\.[a-z0-9_]+\b", other.split("not the verdict", 1)[-1]))
    assert not listed & set(d.found), (d.found, other)
