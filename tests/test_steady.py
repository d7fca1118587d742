"""Steady-state detection (fxcontact.steady.steady_window) on series with a known answer."""

import numpy as np
import pytest

from fxcontact.steady import steady_window


def _rows(values, **extra):
    return [dict(f=float(v), **{k: e[i] for k, e in extra.items()}) for i, v in enumerate(values)]


def test_exponential_approach_found_where_the_change_drops_below_tol():
    """f = 1 - exp(-n/5): found at the first n where the means of the last two windows agree
    to tol (a direct scan of the series), and not before."""
    f = 1.0 - np.exp(-np.arange(200) / 5.0)
    w, tol = 10, 1e-3
    first = next(n for n in range(2 * w, 201)
                 if abs(f[n - w:n].mean() - f[n - 2 * w:n - w].mean()) <= tol * abs(f[n - w:n].mean()))
    found = next(n for n in range(1, 201) if steady_window(_rows(f[:n]), ["f"], w, tol) is not None)
    assert found == first
    assert steady_window(_rows(f[:found]), ["f"], w, tol) == found - w


def test_oscillation_about_a_constant_is_steady_and_a_drift_is_not():
    n = np.arange(60)
    osc = 100.0 + 5.0 * np.sin(2 * np.pi * n / 5.0)         # period 5 = a window of 10 holds 2
    assert steady_window(_rows(osc), ["f"], 10, 1e-3) == 50
    drift = 100.0 + 0.5 * n                                 # +5 per window = 4 % of the mean
    assert steady_window(_rows(drift), ["f"], 10, 0.01) is None
    assert steady_window(_rows(drift), ["f"], 10, 0.05) == 50


def test_every_key_and_the_ready_predicate_must_hold():
    n = np.arange(40)
    rows = [dict(f=1.0, g=float(k), front=float(k)) for k in n]
    assert steady_window(rows, ["f"], 5, 1e-6) == 35
    assert steady_window(rows, ["f", "g"], 5, 1e-6) is None
    assert steady_window(rows, ["f"], 5, 1e-6, ready=lambda q: q["front"] > 35) is None
    assert steady_window(rows, ["f"], 5, 1e-6, ready=lambda q: q["front"] >= 30) == 35
    assert steady_window(rows[:9], ["f"], 5, 1e-6) is None          # fewer than two windows


def test_zero_and_nan():
    assert steady_window(_rows(np.zeros(10)), ["f"], 5, 1e-3) == 5
    assert steady_window(_rows([0.0] * 5 + [1e-9] * 5), ["f"], 5, 1e-3) is None
    assert steady_window(_rows([np.nan] * 10), ["f"], 5, 1e-3) is None


@pytest.mark.parametrize("kw, match", [(dict(window=0), "window"), (dict(tol=0.0), "tol"),
                                       (dict(tol=np.nan), "tol"), (dict(keys=[]), "keys")])
def test_bad_input(kw, match):
    args = dict(rows=_rows(np.ones(10)), keys=["f"], window=5, tol=1e-3)
    with pytest.raises(ValueError, match=match):
        steady_window(**{**args, **kw})
