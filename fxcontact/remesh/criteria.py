"""When to remesh: pure functions of the mesh and the fields, and their collective check.

* quality: the smallest shape quality of the cells (:func:`fxcontact.mesh_health.
  simplex_measures`: 1 for a regular tetrahedron, → 0 for a flat one, negative inverted);
* volume ratio: the smallest ratio of a cell's volume to its volume at the last remesh;
* strain increment: the largest increase of the equivalent strain of a cell since the last
  remesh (a cell that deformed by that much has moved its distortion into the results);
* increments: how many increments have passed since the last remesh
  (:class:`~fxcontact.remesh.remeshing.Remeshing`: a count, not a measure);
* contact coverage: how many elements span the contact zone of a tool — the zone's width
  (its smallest in-surface extent, from the second moments of the contact nodes' positions:
  2√3 × the standard deviation along the smallest principal direction in the surface, the
  width of a uniform strip) over the mean edge length there. A bite spanned by fewer than
  two or three elements gives a coarse, noisy contact pressure.

Everything is numpy (no numba kernel here), local functions first and the collective
reductions in :func:`check`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Union

import numpy as np
from mpi4py import MPI

from fxcontact.mesh_health import simplex_measures

__all__ = ["RemeshCriteria", "quality_and_volume_ratio", "strain_increment",
           "zone_moments", "elements_across", "coverage_reasons", "check"]


def quality_and_volume_ratio(P: np.ndarray, vol_ref: np.ndarray):
    """(min quality, min volume ratio) of the simplices P (N, d+1, d) against their volumes
    ``vol_ref`` (N,) at the last remesh (signed: an inverted cell has a negative ratio and
    quality); (inf, inf) for no cells (local)."""
    if len(P) == 0:
        return math.inf, math.inf
    vol, q = simplex_measures(P)
    ratio = vol / vol_ref
    return float(np.min(np.sign(ratio) * q)), float(np.min(ratio))


def strain_increment(strain: np.ndarray, strain_ref: np.ndarray) -> float:
    """The largest increase of the equivalent strain since ``strain_ref`` (local; 0 for no
    cells)."""
    d = np.asarray(strain) - np.asarray(strain_ref)
    return float(np.max(d)) if d.size else 0.0


def zone_moments(x: np.ndarray) -> np.ndarray:
    """(13,) the count, sums Σx (3) and Σx xᵀ (9) of points x (n, 3): summed over the ranks
    they give the zone's mean and covariance (local)."""
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    return np.r_[len(x), x.sum(axis=0), (x.T @ x).ravel()]


def elements_across(moments: np.ndarray, h: float) -> float:
    """Elements spanning the contact zone of the (summed) :func:`zone_moments` with mean edge
    length ``h``: the width 2√3 σ along the zone's smallest principal direction in its surface
    (the middle eigenvalue of the covariance: the smallest is the surface's normal), over h.
    0 for fewer than 3 contact nodes; inf for a zone that is a straight line of nodes."""
    n = moments[0]
    if n < 3 or not h > 0:
        return 0.0
    mean = moments[1:4] / n
    cov = moments[4:].reshape(3, 3) / n - np.outer(mean, mean)
    ev = np.sort(np.linalg.eigvalsh(cov))
    return 2.0 * math.sqrt(3.0 * max(ev[1], 0.0)) / h


@dataclass
class RemeshCriteria:
    """Thresholds that call for a remesh (None: not checked).

    Args:
        min_quality: remesh when a cell's quality falls below it (e.g. 0.15).
        min_volume_ratio: … a cell's volume over its volume at the last remesh falls below it.
        max_strain_increment: … a cell's equivalent strain grew by more since the last remesh.
        min_elements_across: … a contact zone is spanned by fewer elements (zones of fewer than
            3 nodes are not checked: no contact yet); a number for every tool, or
            ``{tool name: number}`` for the tools named (the bites, not the guides).
        every: … this many increments have passed since the last remesh (or the start): a
            refinement placed in front of a tool that the body moves under (a ring turning
            under its rolls) is placed again before the refined part has passed the tool.
    """

    min_quality: Optional[float] = 0.15
    min_volume_ratio: Optional[float] = 0.05
    max_strain_increment: Optional[float] = None
    min_elements_across: Union[float, Dict[str, float], None] = None
    every: Optional[int] = None

    def __post_init__(self):
        # a threshold that can never be crossed (NaN, out of its range) would switch remeshing
        # off in silence: refused, with the range
        for name, lo, hi, what in (("min_quality", 0.0, 1.0, "a cell quality, in (0, 1)"),
                                   ("min_volume_ratio", 0.0, 1.0, "a volume ratio, in (0, 1)"),
                                   ("max_strain_increment", 0.0, math.inf,
                                    "an equivalent strain increment, > 0")):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float, np.integer, np.floating))
                                      and lo < v < hi):
                raise ValueError(f"RemeshCriteria.{name} must be {what} (or None: not "
                                 f"checked), got {v!r}")
        across = self.min_elements_across
        values = across.values() if isinstance(across, dict) else [across]
        for v in values:
            if v is not None and not (isinstance(v, (int, float, np.integer, np.floating))
                                      and math.isfinite(v) and v > 0):
                raise ValueError(f"RemeshCriteria.min_elements_across must be a number of "
                                 f"elements > 0 (or {{tool: number}}, or None), got {across!r}")
        if self.every is not None and not (isinstance(self.every, (int, np.integer))
                                           and self.every >= 1):
            raise ValueError(f"RemeshCriteria.every must be an integer >= 1 (increments), or "
                             f"None, got {self.every!r}")


def _mean_edge(P: np.ndarray) -> tuple:
    """(Σ edge lengths, count) of the triangles or tetrahedra P (N, k, 3) (local)."""
    k = P.shape[1] if P.ndim == 3 else 0
    s = sum(np.sum(np.linalg.norm(P[:, i] - P[:, j], axis=1)) for i in range(k)
            for j in range(i + 1, k))
    return float(s), len(P) * k * (k - 1) // 2


def coverage_reasons(across: Dict[str, float],
                     limits: Union[float, Dict[str, float], None]) -> List[str]:
    """The reasons to remesh of the contact zones spanned by fewer elements than their
    limit (a number for every zone, ``{name: number}`` or None; zones of 0, no contact, are
    not checked)."""
    if limits is None:
        return []
    if not isinstance(limits, dict):
        limits = {name: limits for name in across}
    return [f"contact '{name}' spanned by {a:.2g} < {limits[name]:g} elements"
            for name, a in across.items()
            if limits.get(name) is not None and 0.0 < a < limits[name]]


def check(comm, criteria: RemeshCriteria, cells: np.ndarray, vol_ref: np.ndarray,
          strain: Optional[np.ndarray] = None, strain_ref: Optional[np.ndarray] = None,
          contact_zones: Optional[Dict[str, tuple]] = None) -> Dict[str, object]:
    """The measures and the reasons to remesh (collective; the same answer on every rank).

    Args:
        cells: (N, 4, 3) vertex positions of the owned cells now; ``vol_ref`` their signed
            volumes at the last remesh.
        strain, strain_ref: the equivalent strain of the owned cells now and at the last remesh.
        contact_zones: ``{name: (points (n, 3), facets (m, 3, 3))}``: the owned contact nodes
            of a tool and the boundary facets around them (vertex positions), per tool.
    Returns:
        ``{"min_quality", "min_volume_ratio", "max_strain_increment", "elements_across":
        {name: value}, "reasons": [str, ...]}`` (an empty ``reasons``: no remesh needed).
    """
    q, r = quality_and_volume_ratio(cells, vol_ref)
    q = comm.allreduce(q, op=MPI.MIN)
    r = comm.allreduce(r, op=MPI.MIN)
    de = 0.0
    if strain is not None:
        de = comm.allreduce(strain_increment(strain, strain_ref), op=MPI.MAX)
    across = {}
    for name, (pts, facets) in sorted((contact_zones or {}).items()):
        m = comm.allreduce(zone_moments(pts), op=MPI.SUM)
        s, c = _mean_edge(np.asarray(facets, dtype=float).reshape(-1, 3, 3))
        s, c = comm.allreduce(np.array([s, c]), op=MPI.SUM)
        across[name] = elements_across(m, s / c if c else 0.0)
    reasons: List[str] = []
    c = criteria
    if c.min_quality is not None and q < c.min_quality:
        reasons.append(f"min quality {q:.3g} < {c.min_quality:g}")
    if c.min_volume_ratio is not None and r < c.min_volume_ratio:
        reasons.append(f"min volume ratio {r:.3g} < {c.min_volume_ratio:g}")
    if c.max_strain_increment is not None and de > c.max_strain_increment:
        reasons.append(f"strain increment {de:.3g} > {c.max_strain_increment:g}")
    reasons += coverage_reasons(across, c.min_elements_across)
    return {"min_quality": q, "min_volume_ratio": r, "max_strain_increment": de,
            "elements_across": across, "reasons": reasons}
