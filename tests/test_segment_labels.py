"""SegmentLabels (a log's labels as runs) against the object array of one label a sample that it
stands in for: every reading the commands make of it gives numpy's answer on that array."""
import numpy as np
import pytest

from components.logs.labels import SegmentLabels

ALPHABET = np.array(["pos1", "pos2", "move-3", "ü-rest", "", "a,b", "pos1 "], dtype=object)


def _labels(rng, n_runs: int) -> np.ndarray:
    """One label a sample: *n_runs* runs of random lengths (1-40), a label may come back later."""
    runs = [rng.choice(ALPHABET) for _ in range(n_runs)]
    return np.array([lab for lab in runs for _ in range(int(rng.integers(1, 40)))], dtype=object)


@pytest.mark.parametrize("seed", range(6))
def test_readings_equal_the_object_array(seed):
    rng = np.random.default_rng(seed)
    x = _labels(rng, int(rng.integers(1, 30)))
    s = SegmentLabels.of(x)
    n = len(x)
    assert len(s) == n and s.shape == (n,)
    assert list(s) == list(x) and np.array_equal(np.asarray(s), x)
    # runs: the changes of the array, and no more (equal neighbours are one run)
    change = np.concatenate([[0], np.flatnonzero(x[1:] != x[:-1]) + 1])
    assert np.array_equal(s.starts, change)
    assert [(a, b, lab) for a, b, lab in s.runs()] == [
        (int(a), int(b), x[a]) for a, b in zip(change, np.append(change[1:], n))]
    assert s.distinct() == sorted(set(x))
    for lab in list(ALPHABET) + ["absent"]:
        assert np.array_equal(s == lab, x == lab), lab
        assert np.array_equal(s != lab, x != lab), lab
    for want in (["pos1"], ["pos2", "", "absent"], []):
        assert np.array_equal(s.isin(want), np.isin(x, want)), want
    for _ in range(20):
        a, b = sorted(rng.integers(-n - 3, n + 3, 2))
        for key in (slice(a, b), slice(a, None), slice(None, b), slice(a, b, 3)):
            got = s[key]
            assert list(got) == list(x[key]), key
        idx = rng.integers(-n, n, 7)
        assert np.array_equal(s[idx], x[idx])
        assert s[int(idx[0])] == x[int(idx[0])]
    mask = rng.random(n) < 0.3
    assert np.array_equal(s[mask], x[mask])
    with pytest.raises(IndexError):
        s[n]


def test_concatenate_and_slices_of_slices():
    rng = np.random.default_rng(11)
    parts = [_labels(rng, k) for k in (3, 1, 7)] + [np.zeros(0, dtype=object)]
    got = SegmentLabels.concatenate([SegmentLabels.of(p) for p in parts])
    want = np.concatenate(parts)
    assert list(got) == list(want)
    # runs across a seam with one label are one run
    assert np.array_equal(got.starts, np.concatenate([[0], np.flatnonzero(want[1:] != want[:-1]) + 1]))
    inner = got[5:-5][3:40]
    assert list(inner) == list(want[5:-5][3:40])


def test_memory_is_the_runs_not_the_samples():
    n = 3_000_000
    # (made from a code a sample, as the readers make them: the runs are found, not given)
    x = SegmentLabels.from_codes(np.repeat([0, 1, 0], [1_000_000, 1_500_000, 500_000]), ["rest", "turn"])
    assert len(x) == n and x.starts.nbytes + x.codes.nbytes < 100  # three runs, whatever the samples
    assert int((x == "turn").sum()) == 1_500_000
    assert x[999_999] == "rest" and x[1_000_000] == "turn" and x[-1] == "rest"
    assert len(x[10:2_000_000].starts) == 2


def test_labels_that_are_not_text_are_refused_naming_the_sample():
    with pytest.raises(ValueError, match=r"sample 3: 7; expected text"):
        SegmentLabels.of(np.array(["a", "a", 7], dtype=object))
    with pytest.raises(ValueError, match="one label a sample"):
        SegmentLabels.of(np.array([["a"]], dtype=object))
    assert len(SegmentLabels.of([])) == 0 and list(SegmentLabels.of([])) == []
