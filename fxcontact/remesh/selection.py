"""Facet selections that remember where they came from, so that a remesh can re-select them.

:meth:`Simulation.facets <fxcontact.simulation.Simulation.facets>` returns a
:class:`FacetSelection`: the local facet indices (an ``np.ndarray``, used as before) that also
know the facet tags and the tag values they were selected by. The set-up calls that take facets
(``add_velocity_bc``, ``add_reaction``, ``add_symmetry_plane``) are recorded by
:func:`remembered`; after a remesh they are made again, in the same order, with the facets of the
same tags on the new mesh (:func:`rederived_calls`). An array derived from a selection (a slice,
a mask, a concatenation) or built by hand has no origin and cannot be re-derived: a remesh
refuses it, naming the call.
"""

from __future__ import annotations

import functools
import inspect
from typing import List, Optional, Tuple

import numpy as np

__all__ = ["FacetSelection", "remembered", "rederived_calls", "facet_tags_of"]


class FacetSelection(np.ndarray):
    """Local facet indices selected by ``tags`` in ``facet_tags`` (an int32 array).

    Attributes:
        facet_tags: the MeshTags the facets were selected in (None for a derived array).
        tags: the tag values (a tuple; None for a derived array).
    """

    def __new__(cls, facets, facet_tags, tags):
        obj = np.asarray(facets, dtype=np.int32).view(cls)
        obj.facet_tags = facet_tags
        obj.tags = tuple(int(t) for t in ([tags] if np.isscalar(tags) else tags))
        return obj

    def __array_finalize__(self, obj):
        # a slice, a mask or arithmetic of a selection is another set of facets: no origin
        self.facet_tags = None
        self.tags = None

    def __reduce__(self):   # pickled (sent between ranks) as a plain array
        return np.asarray(self).__reduce__()


def _origin(facets) -> Optional[Tuple]:
    if isinstance(facets, FacetSelection) and facets.tags is not None:
        return facets.facet_tags, facets.tags
    return None


def remembered(method):
    """Record a successful set-up call of a Simulation that takes ``facets`` (in
    ``sim._facet_calls``, in order), unless it is made from within another recorded call
    (``add_symmetry_plane`` adds a velocity condition itself)."""
    params = list(inspect.signature(method).parameters)[1:]

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        depth = getattr(self, "_facet_call_depth", 0)
        self._facet_call_depth = depth + 1
        try:
            out = method(self, *args, **kwargs)
        finally:
            self._facet_call_depth = depth
        if depth == 0:
            call = dict(zip(params, args), **kwargs)
            self.__dict__.setdefault("_facet_calls", []).append((method.__name__, call))
        return out
    wrapper.remembered = True
    return wrapper


def _call_label(k: int, name: str, call: dict) -> str:
    label = call.get("name")
    return f"{name}() call #{k}" + (f" ('{label}')" if isinstance(label, str) else "")


def facet_tags_of(sim, extra=()) -> object:
    """The one MeshTags object every recorded facet selection (and ``extra`` MeshTags, e.g.
    the contact boundaries') was made from; ValueError naming the call whose facets cannot be
    re-derived (built by hand, derived from a selection) or that used other facet tags.
    None if there is none at all."""
    found = [(f"{_call_label(k, n, c)}", _origin(c.get("facets")))
             for k, (n, c) in enumerate(getattr(sim, "_facet_calls", []))]
    for label, origin in found:
        if origin is None:
            raise ValueError(f"remesh: the facets of {label} cannot be re-derived on a new mesh "
                             f"(an array built by hand or cut from a selection): select them "
                             f"with sim.facets(facet_tags, tags) so that a remesh can select "
                             f"the same tags on the new boundary")
    tags = [o[0] for _, o in found] + [t for t in extra if t is not None]
    for t in tags[1:]:
        if t is not tags[0]:
            raise ValueError("remesh: the facet selections and contact boundaries were made "
                             "from different facet tags objects: make every selection from "
                             "the one facet MeshTags of the mesh")
    return tags[0] if tags else None


def rederived_calls(sim, facet_tags) -> List[Tuple[str, dict]]:
    """The recorded calls with their facets selected again by the same tags in
    ``facet_tags`` (the new mesh's; collective)."""
    out = []
    for name, call in getattr(sim, "_facet_calls", []):
        sel = call["facets"]
        out.append((name, dict(call, facets=sim.facets(facet_tags, sel.tags))))
    return out
