"""The arguments of a heat step read and checked (local checks, no collective operation), and
the collective frame that raises their errors and issues their warnings on every rank.

* :func:`checks_together`: like :func:`fxcontact.collective.together`, and the UserWarnings of
  the block (units, temperatures in kelvin) are issued on every rank, once each;
* :func:`contact_entries`: the ``contact`` argument of :meth:`HeatProblem.step
  <fxcontact.heat.problem.HeatProblem.step>` as a list of :class:`ToolExchange`;
* :func:`nodal_entries`, :func:`positive_dt`, :func:`cell_values`: the other arguments.
"""

from __future__ import annotations

import math
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from fxcontact.collective import check_together
from fxcontact.heat.materials import CONTACT_H_WARN, check_temperature, film_coefficient

__all__ = ["ToolExchange", "cell_values", "checks_together", "contact_entries", "index_array",
           "nodal_entries", "positive_dt"]


@contextmanager
def checks_together(comm, where: str):
    """``with checks_together(comm, "f()") as agree:`` local checks of a call made by every
    rank; ``agree`` is a dict the block fills with values that must be the same on every rank.
    On leaving, an error of any rank is raised on every rank, and the UserWarnings the block
    issued on any rank are issued on every rank (:func:`fxcontact.collective.check_together`:
    one allgather). The block must not contain a collective operation."""
    agree = {}
    error = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield agree
        except Exception as e:  # noqa: BLE001 (raised on every rank by check_together)
            error = e
    notes = [str(w.message) for w in caught]
    got = check_together(comm, where, error, share=notes, **agree)
    for msg in dict.fromkeys(m for g in got for m in g):
        warnings.warn(msg, UserWarning, stacklevel=4)


def positive_dt(dt) -> float:
    try:
        v = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt must be a number of seconds, got {dt!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise ValueError(f"dt must be finite and > 0 (s), got {dt!r}")
    return v


def index_array(what: str, idx, n_local: int) -> np.ndarray:
    """``idx`` as int32 local indices in [0, n_local): ValueError naming ``what`` otherwise."""
    a = np.asarray(idx)
    if a.ndim != 1 or (a.size and a.dtype.kind not in "iu"):
        raise ValueError(f"{what} must be a 1-D array of integer local P1 dof indices, got "
                         f"shape {a.shape} of {a.dtype}")
    a = a.astype(np.int64)
    bad = (a < 0) | (a >= n_local)
    if bad.any():
        raise ValueError(f"{what}: {int(bad.sum())} index(es) outside [0, {n_local}), the local "
                         f"dofs (owned and ghost) of the temperature, e.g. {int(a[bad][0])}")
    return a.astype(np.int32)


def per_vertex(what: str, value, n: int) -> np.ndarray:
    """A number or an array of n numbers as an array of n floats, finite."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number or an array of numbers, got "
                         f"{type(value).__name__}") from None
    if a.ndim == 0:
        if not math.isfinite(float(a)):
            raise ValueError(f"{what} must be finite, got {float(a)!r}")
        a = np.full(n, float(a))
    elif a.shape != (n,):
        raise ValueError(f"{what} must be a number or one value per vertex ({n}), got shape "
                         f"{a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite, got {int((~np.isfinite(a)).sum())} NaN or "
                         f"infinite value(s)")
    return a


@dataclass
class ToolExchange:
    """One entry of the ``contact`` argument: exchange h (T_tool − T) through the area S_n at
    each listed vertex, replacing the air there.

    Attributes:
        name: the key of the entry in the step's balance (``tools``).
        dofs: (n,) local P1 dofs (owned and ghost; the ghosts are left to their owner).
        h: (n,) film coefficients, N/(mm s K).
        temperature: (n,) tool temperatures, °C.
        areas: (n,) areas S_n given by the caller (mm²), or None: the problem's own.
    """

    name: object
    dofs: np.ndarray
    h: np.ndarray
    temperature: np.ndarray
    areas: np.ndarray | None = None


def _one_contact(name, entry, n_local: int) -> ToolExchange:
    what = f"contact[{name!r}]"
    if not isinstance(entry, tuple) or len(entry) not in (3, 4):
        raise ValueError(f"{what} must be a tuple (vertices, h_c, T_tool) or (vertices, h_c, "
                         f"T_tool, areas), got {type(entry).__name__}"
                         f"{'' if not isinstance(entry, tuple) else f' of length {len(entry)}'}")
    dofs = index_array(f"{what} vertices", entry[0], n_local)
    n = len(dofs)
    h = film_coefficient(f"{what} h_c", per_vertex(f"{what} h_c", entry[1], n), CONTACT_H_WARN)
    T = check_temperature(f"{what} T_tool", per_vertex(f"{what} T_tool", entry[2], n))
    areas = None
    if len(entry) == 4 and entry[3] is not None:
        areas = per_vertex(f"{what} areas", entry[3], n)
        if n and areas.min() < 0:
            raise ValueError(f"{what} areas must be ≥ 0 (mm²), got {areas.min():g}")
    return ToolExchange(name, dofs, h, T, areas)


def contact_entries(contact, n_local: int) -> list[ToolExchange]:
    """The ``contact`` argument of a step: None; one tuple ``(vertices, h_c, T_tool[,
    areas])``; a list of such tuples (one per tool, named 0, 1, ... in the balance); or a dict
    {name: tuple}. Local checks."""
    if contact is None:
        return []
    if isinstance(contact, dict):
        items = list(contact.items())
    elif isinstance(contact, tuple):
        items = [(0, contact)]
    elif isinstance(contact, list):
        items = list(enumerate(contact))
    else:
        msg = (f"contact must be a tuple (vertices, h_c, T_tool), a list of such tuples or a "
               f"dict {{name: tuple}}, got {type(contact).__name__}")
        raise ValueError(msg)  # noqa: TRY004
    return [_one_contact(name, entry, n_local) for name, entry in items]


def nodal_entries(nodal_heat, n_local: int):
    """The ``nodal_heat`` argument ``(vertices, Q)`` as (dofs, Q) arrays, or None. Local."""
    if nodal_heat is None:
        return None
    if not isinstance(nodal_heat, tuple) or len(nodal_heat) != 2:
        raise ValueError("nodal_heat must be a tuple (vertices, Q): local P1 dofs and the heat "
                         "flow into the body at each, N mm/s")
    dofs = index_array("nodal_heat vertices", nodal_heat[0], n_local)
    return dofs, per_vertex("nodal_heat Q", nodal_heat[1], len(dofs))


def cell_values(source, n_owned: int, n_local: int):
    """The ``source`` argument as (values, owned_only) for a DG0 array, or None. ``source``: a
    number, a DG0 Function of the mesh, or an array of the local cells (owned and ghost) or of
    the owned cells. Local."""
    if source is None:
        return None
    if hasattr(source, "function_space") and hasattr(source, "x"):
        e = source.function_space.ufl_element()
        if e.degree() != 0 or e.family() not in ("DG", "Discontinuous Lagrange") \
                or source.function_space.dofmap.index_map_bs != 1:
            raise ValueError(f"source: a Function source must be scalar DG0 (one value per "
                             f"cell), got the element {e}")
        source = source.x.array
    a = np.asarray(source, dtype=float)
    if a.ndim == 0:
        a = np.full(n_local, float(a))
    if a.ndim != 1 or len(a) not in (n_owned, n_local):
        raise ValueError(f"source must be a number, a DG0 Function or one value per local cell "
                         f"(owned and ghost: {n_local}; or owned: {n_owned}), got shape "
                         f"{a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"source must be finite (N/(mm² s) = W/mm³), got "
                         f"{int((~np.isfinite(a)).sum())} NaN or infinite value(s)")
    return a, len(a) == n_owned and n_owned != n_local
