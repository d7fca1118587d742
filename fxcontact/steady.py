"""Steady-state detection for the process demos (drawing, rolling): a run is steady once the
means of the monitored quantities over two consecutive windows of increments agree.

Window means, not single increments, are compared because the nodal contact forces of a
forming process oscillate as the nodes pass into the contact zone (one period per element
passage); the window should span several such passages.
"""

from typing import Callable, Optional, Sequence

import numpy as np

__all__ = ["steady_window"]


def steady_window(rows: Sequence[dict], keys: Sequence[str], window: int, tol: float,
                  ready: Optional[Callable[[dict], bool]] = None) -> Optional[int]:
    """Index of the first row of the steady window, or ``None`` if not (yet) steady.

    Args:
        rows: the history, one dict per increment (oldest first).
        keys: the quantities that must be steady (e.g. force and torque).
        window: increments per window (≥ 1); the last ``2 window`` rows are examined.
        tol: largest relative change ``|m1 - m0| / |m1|`` of each key's window mean.
        ready: optional predicate every row of both windows must satisfy (e.g. the front has
            left the contact zone).

    Returns ``len(rows) - window`` (the last window is the steady one) when every key's two
    window means agree within ``tol``; a key whose last mean is zero must have both means 0.
    """
    window = int(window)
    if window < 1:
        raise ValueError(f"window must be >= 1 increment, got {window}")
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a finite number > 0, got {tol!r}")
    if not keys:
        raise ValueError("keys must name at least one monitored quantity")
    if len(rows) < 2 * window:
        return None
    both = list(rows[-2 * window:])
    if ready is not None and not all(ready(q) for q in both):
        return None
    for key in keys:
        m0 = float(np.mean([q[key] for q in both[:window]]))
        m1 = float(np.mean([q[key] for q in both[window:]]))
        if not (np.isfinite(m0) and np.isfinite(m1)) or abs(m1 - m0) > tol * abs(m1):
            return None
    return len(rows) - window
