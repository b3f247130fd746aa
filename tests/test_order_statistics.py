"""The median of a long array: np.median's value, bit for bit, whatever the sample that
brackets it sees (the bracket is a shortcut; the counts decide)."""
import numpy as np
import pytest

from components.estimation import order_statistics
from components.estimation.order_statistics import BINS, DIRECT_BELOW, SAMPLE, median

N = 3 * DIRECT_BELOW + 7          # odd
STRIDE = N // SAMPLE


def _arrays():
    rng = np.random.default_rng(11)
    normal = rng.standard_normal(N) * 1e-4 + 3e-3
    yield "normal, odd count", normal
    yield "normal, even count", normal[:-1]
    yield "quantised (ties everywhere)", np.round(normal * 2e4) / 2e4
    yield "one value", np.full(N, 0.005)
    yield "sorted", np.sort(normal)
    yield "reversed", np.sort(normal)[::-1].copy()
    heavy = rng.standard_t(1.5, N)
    yield "heavy tails", heavy
    # the strided sample sees only the outliers: its bracket misses the middle
    spiked = normal.copy()
    spiked[::STRIDE] = 1e6
    yield "sample all high", spiked
    sunk = normal.copy()
    sunk[::STRIDE] = -1e6
    yield "sample all low", sunk
    # the sample's bracket is one value that does not cover the middle ranks
    ties = np.where(np.arange(N) % STRIDE == 0, 0.0, rng.standard_normal(N))
    yield "sample on a tie", ties
    yield "two values, middle on their boundary", np.repeat([1.0, 2.0], N // 2)
    # a regular clock's intervals: alike but for their last bits, so any bracket holds them all
    yield "a regular clock's intervals", np.diff(12345.0 + np.arange(N + 1) * 1e-3)


@pytest.mark.parametrize("name,values", list(_arrays()), ids=[n for n, _ in _arrays()])
def test_the_median_is_numpys_bit_for_bit(name, values):
    expected = np.median(values)
    got = median(values.copy(), overwrite_input=True)
    assert got == expected, (name, got, expected)


def test_a_long_array_is_left_as_it_was():
    values = np.random.default_rng(3).standard_normal(N)
    before = values.copy()
    median(values, overwrite_input=True)
    assert np.array_equal(values, before)


def test_the_bracket_is_what_answers_a_long_array(monkeypatch):
    """The shortcut is taken (not the fallback) on an ordinary long array."""
    calls = []
    real = np.median
    monkeypatch.setattr(order_statistics.np, "median", lambda *a, **k: calls.append(1) or real(*a, **k))
    values = np.random.default_rng(5).standard_normal(N)
    assert median(values) == real(values)
    assert calls == []


@pytest.mark.parametrize("name,values", list(_arrays()), ids=[n for n, _ in _arrays()])
def test_the_median_of_pieces_is_numpys_whatever_the_cuts_and_the_sample(name, values):
    """The values in uneven pieces, never joined (unless the bracket misses): np.median's value,
    with the strided sample and with a sample of only the lowest values (a bracket off the middle)."""
    from components.estimation.order_statistics import median_of_pieces, stride

    cuts = np.sort(np.random.default_rng(5).choice(np.arange(1, len(values)), 40, replace=False))
    parts = np.split(values, cuts)
    expected = np.median(values)
    for sample in (values[::stride(len(values))], np.sort(values)[:SAMPLE]):
        got = median_of_pieces(lambda: iter(parts), len(values), sample)
        assert got == expected, (name, got, expected)


@pytest.mark.parametrize("name,values", list(_arrays()), ids=[n for n, _ in _arrays()])
def test_a_bracket_too_full_to_hold_is_narrowed_by_its_bins(name, values, monkeypatch):
    """With a bracket allowed to hold only 1000 values, np.median's value still, bit for bit,
    and no piece of values gathered beyond that many (memory bounded whatever the log's length)."""
    from components.estimation.order_statistics import median_of_pieces, stride

    monkeypatch.setattr(order_statistics, "MOST_INSIDE", 1000)
    held = []
    real_concatenate = np.concatenate
    monkeypatch.setattr(order_statistics.np, "concatenate",
                        lambda arrays, *a, **k: held.append(sum(len(x) for x in arrays)) or real_concatenate(arrays, *a, **k))
    parts = np.array_split(values, 37)
    expected = np.median(values)
    for sample in (values[::stride(len(values))], np.sort(values)[:SAMPLE], np.zeros(0)):
        held.clear()
        got = median_of_pieces(lambda: iter(parts), len(values), sample)
        assert got == expected, (name, got, expected)
        assert all(h <= 1000 for h in held if h != BINS + 1), (name, held)
