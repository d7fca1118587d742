"""What a :class:`~fxcontact.simulation.Simulation` registers, and how its messages name it.

The velocity conditions (:class:`VelocityCondition`: the dolfinx condition, its value, and its
label in the messages), the values they take at a time (:func:`time_value`), the labels of the
registered objects and of their history columns, and the checks that an object is added once and
that two of them do not write the same history column.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np
from mpi4py import MPI

from fxcontact.protocols import HasDiagnostics

__all__ = ["VelocityCondition", "bc_label", "time_value", "label", "column_labels",
           "check_added_once", "merge_columns"]


@dataclass
class VelocityCondition:
    """A velocity condition: the dolfinx condition, the function it imposes, its value (a
    constant or a function of x and/or t) and the gdim of a vector value (None for a component)."""

    bc: object
    g: object
    value: object
    gdim: Optional[int]
    #: how the messages name it: number, component, facets
    label: str = "velocity boundary condition"


def bc_label(sim, k: int, facets, component) -> str:
    """``velocity boundary condition #k (component c, on n facets)`` (collective)."""
    fdim = sim.mesh.topology.dim - 1
    owned = sim.mesh.topology.index_map(fdim).size_local
    n = sim.comm.allreduce(int(np.sum(np.asarray(facets) < owned)), op=MPI.SUM)
    comp = "all components" if component is None else f"component {component}"
    return f"velocity boundary condition #{k} ({comp}, on {n} facets)"


def time_value(value, t):
    """A BC value at time t: constants pass through, f(t) is called, f(x) (vectorised) too."""
    if callable(value):
        try:
            params = inspect.signature(value).parameters
        except (TypeError, ValueError):
            params = {}
        if "t" in params and len(params) == 1:
            return value(t)
        if "t" in params:
            return lambda x: value(x, t)
        return value
    return value


def label(obj) -> str:
    """``NodalContact 'die'``: a registered object in messages."""
    name = getattr(obj, "name", None)
    return type(obj).__name__ + (f" '{name}'" if isinstance(name, str) else "")


def column_labels(contributor) -> Dict[str, str]:
    """The labels that start a contributor's history columns, with what each labels: its name
    (a contact's ``{name}_nodes``…) and its tools' names (``{tool}_force_x``…)."""
    out = {}
    for tool in getattr(contributor, "tools", None) or []:
        if isinstance(getattr(tool, "name", None), str):
            out[tool.name] = f"tool '{tool.name}' of {label(contributor)}"
    if isinstance(contributor, HasDiagnostics) and isinstance(getattr(contributor, "name", None),
                                                               str):
        out[contributor.name] = label(contributor)
    return out


def check_added_once(obj, registered, what: str):
    """ValueError if ``obj`` (the same object) is already registered."""
    if any(r is obj for r in registered):
        raise ValueError(f"{what} {label(obj)} is already added to this simulation: added "
                         f"twice, it would act twice (its forces counted twice, its history "
                         f"columns wrong); add it once")


def merge_columns(row: dict, columns: dict, owner):
    """Add ``columns`` to a history row; ValueError if one is already there (two contributors
    or controllers writing the same column would overwrite each other)."""
    clash = sorted(set(row) & set(columns))
    if clash:
        raise ValueError(f"history column(s) {clash} of {label(owner)} are already written "
                         f"by another contributor, reaction or symmetry plane: pass a distinct "
                         f"name= to one of them")
    row.update(columns)
