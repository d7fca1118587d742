"""Rigid surfaces of revolution defined by a meridian profile of lines and circular arcs.

A :class:`RevolvedProfile` is the surface swept by a 2-D profile of the meridian half-plane
``(s, ρ)`` — ``s = (x − a)·w`` along the axis, ``ρ = |P_w(x − a)| ≥ 0`` the radius — about the
axis ``(a, w)`` (THEORY §4.1, "general surface of revolution"). Drawing dies (entry cone, fillet,
bearing land, exit relief), grooved and flanged rolls, punches and mandrels are such surfaces;
:func:`die_profile` and :func:`grooved_roll_profile` build the two standard profiles and
:func:`faceted_revolved` triangulates the same surface for a
:class:`~fxcontact.tools.faceted.FacetedTool`.

Distance (THEORY §4.1). The closest point of a surface of revolution lies in the meridian
half-plane of the point, so the gap is the signed 2-D distance ``g(s, ρ)`` to the profile and

    ∇d = g_s w + g_ρ e_r,
    ∇²d = g_ss w⊗w + g_sρ (w⊗e_r + e_r⊗w) + g_ρρ e_r⊗e_r + (g_ρ/ρ) e_θ⊗e_θ,

with, per feature of the profile,

* a line (free-side unit normal ν, point A): ``g = (q − A)·ν``, ``∇g = ν``, ``∇²g = 0``;
* an arc (centre o, radius r): ``g = κ(|q − o| − r)``, ``∇g = κ e``,
  ``∇²g = κ(I − e⊗e)/|q − o|``, ``e = (q − o)/|q − o|``, ``κ = +1`` if the tool lies on the
  centre side (convex tool), ``−1`` otherwise;
* a vertex V of the profile (a circle in 3-D, a point if V is on the axis):
  ``g = σ|q − V|``, ``∇g = σ e``, ``∇²g = σ(I − e⊗e)/|q − V|``, ``e = (q − V)/|q − V|``.

Every feature is evaluated exactly (no iteration): the closest point is the nearest of the
interior foot points of the segments and arcs and of the vertices, so the distance is exact
everywhere, including at kinks.

Kinks (vertices where the tangent jumps). Non-tangent junctions are allowed.

* *Convex kink* (the tool is convex there: the profile turns towards the tool): the points of
  free space in the wedge between the two segment normals project on the kink itself; the gap
  is the distance to the kink circle, the normal points from the circle to the point, the
  Hessian is that of the distance to a circle (its hoop part included).
* *Concave kink* (the profile turns towards free space): in free space the two segments'
  regions meet on the bisector of the kink, where the gap is continuous but its gradient jumps
  (the medial axis: the closest point is not unique there). On the bisector itself the segment
  that comes first in the profile is taken (deterministic; no flag, as for any medial-axis
  point). Inside the tool, the wedge between the two normals projects on the kink circle.
* The sign of a vertex projection is ``σ = sign((q − V)·m)`` with ``m`` the *pseudo-normal*,
  the normalised sum of the free-side normals of the two segments at V (exact for a simple
  curve, also for tangent and nearly tangent junctions). A point exactly on a kink circle gets
  the gap 0, the normal ``m`` and flag 2 (normal undefined); the 2-D part of its Hessian is 0.

Profile ends. Each end of the profile either lies **on the axis** (``ρ = 0``: the surface is
closed there, like the apex of a cone or the pole of a sphere; the tangent must leave the axis,
``t_ρ > 0``), or the profile is **continued to infinity by its tangent ray** (a line end segment
is simply extended; an arc end gets a straight tangent extension, feature ``2n + 1`` for the
first point and ``2n + 2`` for the last one). The extension must not approach the axis
(``t_ρ ≥ 0`` going outwards): extend or close the profile yourself otherwise. The profile with
its extensions is a simple curve that splits the half-plane in two: the tool and free space, so
the gap is defined and exact everywhere. A one-line profile parallel to the axis is thus an
infinite :class:`~fxcontact.tools.analytic.Cylinder`; a one-line profile starting on the axis
is a :class:`~fxcontact.tools.analytic.Cone`.

Which side is the tool: the ``inside`` flag (required, no default).

* ``inside=True`` — the body is **inside** the surface, between the axis and the surface: a
  drawing die, a bore, a container. Walking along the profile in the direction of increasing
  ``s`` (from the end point with the smaller ``s`` to the other one), the tool is on the side
  of larger ρ (the left, with ``s`` to the right and ρ up).
* ``inside=False`` — the body is **outside**: a roll, a mandrel, a punch. Walking towards
  increasing ``s``, the tool is on the side of smaller ρ (the right).

The direction is taken between the first and the last profile points, so the order in which
the points are given does not matter; a profile whose end points have the same ``s`` is
rejected (ambiguous). For profiles that are graphs ``ρ = R(s)`` (dies, rolls) this is exactly
"tool above" / "tool below"; for a profile closed on the axis at both ends, ``inside=False`` is
the solid of revolution and ``inside=True`` the cavity; a one-line profile from the axis gives
the solid cone (``inside=False``) or the conical bore (``inside=True``) of ``Cone``.

Features (``Projection.feature``) with ``n`` profile segments: ``0 … n−1`` the segment (the end
segments include their straight extension), ``n + i`` the profile point ``i`` (kink circle or
axis point), ``2n + 1`` / ``2n + 2`` the tangent extensions of arc end segments
(:attr:`RevolvedProfile.feature_names` spells them out). Segment and point numbers are those of
the given profile.

Flags: 0 regular; 2 singular — a point on the axis (``ρ ≤ AXIS_TOL·L``, ``L`` the profile size,
:attr:`~RevolvedProfile.length_scale`) whose closest points form a circle (``e_r`` replaced by
:attr:`~RevolvedProfile.e_fixed`, ``1/ρ`` by ``1/(AXIS_TOL·L)`` in the hoop term, as for
``Cylinder``), the centre of the closest arc (all its points are closest; the arc midpoint is
taken and ``1/|q − o|`` replaced by ``1/(AXIS_TOL·r)``), or a point exactly on a kink circle.
Points on the axis whose closest point is on the axis (an axis end of the profile, or an arc
centred on the axis) are regular: their projection is unique.

Backends: ``backend="numba"`` (one ``@numba.njit(cache=True)`` kernel looping over the points)
or ``"numpy"`` (:func:`revolved_numpy`, vectorised reference twin, for testing only).
"""

from __future__ import annotations

import logging
import math
from typing import List, Optional, Tuple

import numba
import numpy as np

from fxcontact.tools.analytic import (AXIS_TOL, AnalyticTool, check_flag, finite_vector,
                                      fixed_perpendicular, float_tuple, readonly_copy)
from fxcontact.tools.base import Projection, RigidMotion, as_points, unit_vector
from fxcontact.tools.revolved_profile import (ARC, LINE, SNAP_TOL, Profile, die_profile,
                                              grooved_roll_profile, positive_number)

__all__ = ["RevolvedProfile", "die_profile", "grooved_roll_profile", "faceted_revolved",
           "revolved_numpy"]

logger = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# numba kernel and numpy twin
# --------------------------------------------------------------------------------------------

@numba.njit(cache=True)
def _revolved_kernel(y, a, w, kind, pfeat, pdat, vdat, vfeat, efix, tol, L, want_h,
                     gap, nrm, pt, hes, feat, flag):  # pragma: no cover - JIT
    er = np.empty(3)
    et = np.empty(3)
    r = np.empty(3)
    K = kind.shape[0]
    J = vdat.shape[0]
    for i in range(y.shape[0]):
        u0 = y[i, 0] - a[0]
        u1 = y[i, 1] - a[1]
        u2 = y[i, 2] - a[2]
        s = u0 * w[0] + u1 * w[1] + u2 * w[2]
        r[0] = u0 - s * w[0]
        r[1] = u1 - s * w[1]
        r[2] = u2 - s * w[2]
        rho = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        # closest feature: interior foot points first, then vertices (ties: first found)
        best = np.inf
        bk = -1
        for k in range(K):
            if kind[k] == 0:
                t = (s - pdat[k, 0]) * pdat[k, 2] + (rho - pdat[k, 1]) * pdat[k, 3]
                if pdat[k, 4] < t < pdat[k, 5]:
                    dd = abs((s - pdat[k, 0]) * pdat[k, 6] + (rho - pdat[k, 1]) * pdat[k, 7])
                    if dd < best:
                        best = dd
                        bk = k
            else:
                dx = s - pdat[k, 0]
                dy = rho - pdat[k, 1]
                dq = math.hypot(dx, dy)
                inner = True
                if dq > 0.0:
                    beta = math.atan2(pdat[k, 4] * dy - pdat[k, 5] * dx,
                                      pdat[k, 4] * dx + pdat[k, 5] * dy)
                    dl = pdat[k, 6]
                    if dl > 0.0:
                        inner = 0.0 < beta < dl
                    else:
                        inner = dl < beta < 0.0
                if inner:
                    dd = abs(dq - pdat[k, 2])
                    if dd < best:
                        best = dd
                        bk = k
        for j in range(J):
            dd = math.hypot(s - vdat[j, 0], rho - vdat[j, 1])
            if dd < best:
                best = dd
                bk = K + j
        # 2-D gap, gradient and Hessian of the chosen feature
        fl = 0
        axis_reg = False
        hoop_sp = 0.0
        hss = 0.0
        hsr = 0.0
        hrr = 0.0
        if bk < K:
            k = bk
            feat[i] = pfeat[k]
            if kind[k] == 0:
                g = (s - pdat[k, 0]) * pdat[k, 6] + (rho - pdat[k, 1]) * pdat[k, 7]
                gs = pdat[k, 6]
                gr = pdat[k, 7]
            else:
                dx = s - pdat[k, 0]
                dy = rho - pdat[k, 1]
                dq = math.hypot(dx, dy)
                kap = pdat[k, 3]
                if dq > tol * pdat[k, 2]:
                    es = dx / dq
                    ep = dy / dq
                    ff = kap / dq
                else:
                    es = pdat[k, 7]
                    ep = pdat[k, 8]
                    ff = kap / (tol * pdat[k, 2])
                    fl = 2
                g = kap * (dq - pdat[k, 2])
                gs = kap * es
                gr = kap * ep
                hss = ff * (1.0 - es * es)
                hsr = -ff * es * ep
                hrr = ff * (1.0 - ep * ep)
                if pdat[k, 9] != 0.0:
                    axis_reg = True
                    hoop_sp = ff
        else:
            j = bk - K
            feat[i] = vfeat[j]
            dx = s - vdat[j, 0]
            dy = rho - vdat[j, 1]
            dv = math.hypot(dx, dy)
            if dv > 0.0:
                es = dx / dv
                ep = dy / dv
                sg = 1.0 if es * vdat[j, 2] + ep * vdat[j, 3] >= 0.0 else -1.0
                g = sg * dv
                gs = sg * es
                gr = sg * ep
                ff = sg / dv
                hss = ff * (1.0 - es * es)
                hsr = -ff * es * ep
                hrr = ff * (1.0 - ep * ep)
                if vdat[j, 1] == 0.0:
                    axis_reg = True
                    hoop_sp = ff
            else:
                g = 0.0
                gs = vdat[j, 2]
                gr = vdat[j, 3]
                if vdat[j, 4] != 0.0:
                    fl = 2
                if vdat[j, 1] == 0.0:
                    axis_reg = True
                    hoop_sp = 0.0
        # 3-D
        if rho > tol * L:
            for m in range(3):
                er[m] = r[m] / rho
            rinv = 1.0 / rho
        else:
            for m in range(3):
                er[m] = efix[m]
            rinv = 1.0 / (tol * L)
            if not axis_reg:
                fl = 2
        hoop = hoop_sp if axis_reg else gr * rinv
        gap[i] = g
        for m in range(3):
            nrm[i, m] = gs * w[m] + gr * er[m]
            pt[i, m] = y[i, m] - g * nrm[i, m]
        if want_h:
            et[0] = w[1] * er[2] - w[2] * er[1]
            et[1] = w[2] * er[0] - w[0] * er[2]
            et[2] = w[0] * er[1] - w[1] * er[0]
            for m in range(3):
                for n in range(3):
                    hes[i, m, n] = (hss * w[m] * w[n] + hsr * (w[m] * er[n] + er[m] * w[n])
                                    + hrr * er[m] * er[n] + hoop * et[m] * et[n])
        flag[i] = fl


def revolved_numpy(y, a, w, kind, pfeat, pdat, vdat, vfeat, efix, tol, L, want_h):
    """Vectorised numpy twin of the revolved-profile kernel. Reference, for testing only."""
    N = y.shape[0]
    u = y - a
    s = u @ w
    rv = u - s[:, None] * w
    rho = np.sqrt(np.einsum("ni,ni->n", rv, rv))
    K, J = kind.shape[0], vdat.shape[0]
    cand = np.full((N, K + J), np.inf)
    for k in range(K):
        p = pdat[k]
        if kind[k] == LINE:
            t = (s - p[0]) * p[2] + (rho - p[1]) * p[3]
            dd = np.abs((s - p[0]) * p[6] + (rho - p[1]) * p[7])
            cand[:, k] = np.where((p[4] < t) & (t < p[5]), dd, np.inf)
        else:
            dx, dy = s - p[0], rho - p[1]
            dq = np.hypot(dx, dy)
            beta = np.arctan2(p[4] * dy - p[5] * dx, p[4] * dx + p[5] * dy)
            inner = ((0.0 < beta) & (beta < p[6])) if p[6] > 0 else ((p[6] < beta) & (beta < 0))
            inner |= dq == 0.0
            cand[:, k] = np.where(inner, np.abs(dq - p[2]), np.inf)
    for j in range(J):
        cand[:, K + j] = np.hypot(s - vdat[j, 0], rho - vdat[j, 1])
    bk = np.argmin(cand, axis=1)  # first minimum, as the kernel's strict comparisons
    g = np.zeros(N)
    gs = np.zeros(N)
    gr = np.zeros(N)
    hss = np.zeros(N)
    hsr = np.zeros(N)
    hrr = np.zeros(N)
    feat = np.zeros(N, np.int64)
    fl = np.zeros(N, np.int64)
    axis_reg = np.zeros(N, bool)
    hoop_sp = np.zeros(N)
    for k in range(K):
        sel = bk == k
        if not np.any(sel):
            continue
        p = pdat[k]
        feat[sel] = pfeat[k]
        ss, rr = s[sel], rho[sel]
        if kind[k] == LINE:
            g[sel] = (ss - p[0]) * p[6] + (rr - p[1]) * p[7]
            gs[sel], gr[sel] = p[6], p[7]
        else:
            dx, dy = ss - p[0], rr - p[1]
            dq = np.hypot(dx, dy)
            ok = dq > tol * p[2]
            dqs = np.where(ok, dq, 1.0)
            es = np.where(ok, dx / dqs, p[7])
            ep = np.where(ok, dy / dqs, p[8])
            ff = np.where(ok, p[3] / dqs, p[3] / (tol * p[2]))
            fl[sel] = np.where(ok, 0, 2)
            g[sel] = p[3] * (dq - p[2])
            gs[sel], gr[sel] = p[3] * es, p[3] * ep
            hss[sel], hsr[sel], hrr[sel] = ff * (1 - es * es), -ff * es * ep, ff * (1 - ep * ep)
            if p[9] != 0.0:
                axis_reg[sel] = True
                hoop_sp[sel] = ff
    for j in range(J):
        sel = bk == K + j
        if not np.any(sel):
            continue
        v = vdat[j]
        feat[sel] = vfeat[j]
        dx, dy = s[sel] - v[0], rho[sel] - v[1]
        dv = np.hypot(dx, dy)
        ok = dv > 0.0
        dvs = np.where(ok, dv, 1.0)
        es, ep = dx / dvs, dy / dvs
        sg = np.where(es * v[2] + ep * v[3] >= 0.0, 1.0, -1.0)
        ff = np.where(ok, sg / dvs, 0.0)
        g[sel] = np.where(ok, sg * dv, 0.0)
        gs[sel] = np.where(ok, sg * es, v[2])
        gr[sel] = np.where(ok, sg * ep, v[3])
        hss[sel], hsr[sel], hrr[sel] = ff * (1 - es * es), -ff * es * ep, ff * (1 - ep * ep)
        fl[sel] = np.where(ok, 0, 2 if v[4] != 0.0 else 0)
        if v[1] == 0.0:
            axis_reg[sel] = True
            hoop_sp[sel] = ff
    reg = rho > tol * L
    rs = np.where(reg, rho, 1.0)
    er = np.where(reg[:, None], rv / rs[:, None], efix)
    rinv = np.where(reg, 1.0 / rs, 1.0 / (tol * L))
    fl = np.where(~reg & ~axis_reg, 2, fl).astype(np.int64)
    hoop = np.where(axis_reg, hoop_sp, gr * rinv)
    nrm = gs[:, None] * w + gr[:, None] * er
    pt = y - g[:, None] * nrm
    if want_h:
        et = np.cross(w, er)
        ww = np.outer(w, w)
        wer = w[None, :, None] * er[:, None, :]
        hes = (hss[:, None, None] * ww + hsr[:, None, None] * (wer + wer.transpose(0, 2, 1))
               + hrr[:, None, None] * er[:, :, None] * er[:, None, :]
               + hoop[:, None, None] * et[:, :, None] * et[:, None, :])
    else:
        hes = np.empty((0, 3, 3))
    return g, nrm, pt, hes, feat, fl


def _revolved_numba(y, a, w, kind, pfeat, pdat, vdat, vfeat, efix, tol, L, want_h):
    n = y.shape[0]
    gap, nrm, pt = np.empty(n), np.empty((n, 3)), np.empty((n, 3))
    hes = np.empty((n, 3, 3) if want_h else (0, 3, 3))
    feat, flag = np.zeros(n, np.int64), np.zeros(n, np.int64)
    _revolved_kernel(y, a, w, kind, pfeat, pdat, vdat, vfeat, efix, tol, L, bool(want_h),
                     gap, nrm, pt, hes, feat, flag)
    return gap, nrm, pt, hes, feat, flag


# --------------------------------------------------------------------------------------------
# the tool
# --------------------------------------------------------------------------------------------

class RevolvedProfile(AnalyticTool):
    """Surface of revolution of a meridian profile of lines and circular arcs (die, roll, ...).

    See the module docstring for the distance, the kinks, the profile ends, the features and
    the flags.

    Args:
        points: (n + 1, 2) profile points ``(s, ρ)``: ``s`` along the axis from ``axis_point``,
            ``ρ >= 0`` the radius. Only the first and last points may lie on the axis.
        arcs: ``None`` (all segments straight) or one entry per segment: ``None`` (or 0) for a
            straight segment, or the **signed radius** of a circular arc from point ``i`` to
            point ``i + 1``: the arc is the minor one (sweep ≤ 180°), turning counter-clockwise
            in the ``(s, ρ)`` plane (``s`` to the right, ρ up) if the radius is positive,
            clockwise if negative; ``|radius|`` must be at least half the chord.
        inside: **required**. ``True``: the body is inside the surface (drawing die, bore,
            container; tool on the large-ρ side). ``False``: the body is outside (roll, mandrel,
            punch; tool on the axis side). See the module docstring for the precise rule.
        axis_point: the point ``a`` of the axis where ``s = 0`` (at ``t = 0``).
        axis: axis direction ``w`` (normalised here); ``s`` increases along it.
        velocity: translation velocity, constant 3-vector or ``v(t)``.
        angular_velocity: rotation ω about the tool's own axis (constant or ``ω(t)``); it does
            not move the surface but enters :meth:`velocity` (``ω w × (P − a)``).
        name: label of the tool.
        backend: ``"numba"`` (default) or ``"numpy"`` (reference twin, for testing only).

    Raises:
        ValueError: bad arguments, or a bad profile (the message names the segment or point):
            non-finite or negative-ρ points, interior points on the axis, zero-length segments,
            a segment on the axis, an arc radius smaller than half the chord, an arc reaching
            the axis, a cusp, a self-intersection (extensions included), an end extension
            approaching the axis, an axis end whose tangent does not leave the axis, end points
            with the same ``s``.

    Example — a drawing die (wire moving along +z)::

        die = RevolvedProfile.die(entry_radius=1.6, exit_radius=1.0, half_angle=np.radians(8),
                                  land_length=0.5, fillet_radius=0.3)
    """

    _kind = "revolved"

    def __init__(self, points, arcs=None, *, inside: bool, axis_point=(0.0, 0.0, 0.0),
                 axis=(0.0, 0.0, 1.0), velocity=(0.0, 0.0, 0.0), angular_velocity=0.0,
                 name: str = "revolved", backend: str = "numba"):
        inside = check_flag(inside, "inside")
        prof = Profile(points, arcs, inside)
        self.profile = prof
        self.points = readonly_copy(prof.points)
        self.arcs = None if arcs is None else tuple(None if (r is None or r == 0) else float(r)
                                                    for r in arcs)
        self.inside = inside
        self.axis_point = readonly_copy(finite_vector(axis_point, "RevolvedProfile axis_point"))
        self.axis = readonly_copy(unit_vector(axis, "RevolvedProfile axis"))
        self.e_fixed = readonly_copy(fixed_perpendicular(self.axis))
        self.length_scale = prof.L
        kind, feat, pdat, vdat, vfeat = prof.arrays()
        self._arrays = (kind, feat, pdat, vdat, vfeat)
        names = {}
        for p in prof.prims:
            names.setdefault(p.feature, p.label)
        for i, m, kink in prof.verts:
            if prof.on_axis[i]:
                where = "axis point, apex" if kink else "axis point, smooth pole"
            else:
                where = "kink circle" if kink else "tangent junction circle"
            names[prof.n + i] = f"point {i} ({where})"
        self.feature_names = dict(sorted(names.items()))
        self._init_common(name, backend,
                          RigidMotion(velocity=velocity, angular_velocity=angular_velocity,
                                      axis_point=float_tuple(self.axis_point),
                                      axis=float_tuple(self.axis)))
        self._frozen = True

    def _params(self):
        kind, feat, pdat, vdat, vfeat = self._arrays
        return (self.axis_point, self.axis, kind, feat, pdat, vdat, vfeat, self.e_fixed,
                AXIS_TOL, self.length_scale)

    def _project_reference(self, y: np.ndarray, hessian: bool) -> Projection:
        y = as_points(y)
        impl = _revolved_numba if self.backend == "numba" else revolved_numpy
        gap, nrm, pt, hes, feat, flag = impl(y, *self._params(), bool(hessian))
        if logger.isEnabledFor(logging.DEBUG):
            n_sing = int(np.count_nonzero(flag == 2))
            if n_sing:
                logger.debug("%s: %d singular point(s) (flag = 2)", self.name, n_sing)
        return Projection(gap, nrm, pt, hes if hessian else None, feat, flag)

    def _repr_fields(self):
        return (f"points={self.points.tolist()}, arcs={self.arcs}, inside={self.inside}, "
                f"axis_point={float_tuple(self.axis_point)}, axis={float_tuple(self.axis)}")

    # -- builders -------------------------------------------------------------------------

    @classmethod
    def die(cls, entry_radius, exit_radius, half_angle, land_length, fillet_radius=0.0,
            relief_angle=None, relief_length=0.0, s0=0.0, **kwargs) -> "RevolvedProfile":
        """Drawing die (body inside) from :func:`die_profile`; ``kwargs`` go to the
        constructor (``axis_point``, ``axis``, ``velocity``, ``name``, ...)."""
        pts, arcs = die_profile(entry_radius, exit_radius, half_angle, land_length,
                                fillet_radius, relief_angle, relief_length, s0)
        kwargs.setdefault("name", "die")
        return cls(pts, arcs, inside=True, **kwargs)

    @classmethod
    def grooved_roll(cls, barrel_radius, barrel_width, groove_radius=0.0, groove_depth=0.0,
                     flange_height=0.0, flange_width=0.0, fillet_radius=0.0, s0=0.0,
                     edge_radius=0.0, **kwargs) -> "RevolvedProfile":
        """Grooved / flanged roll (body outside) from :func:`grooved_roll_profile`; ``kwargs``
        go to the constructor (``axis_point``, ``axis``, ``angular_velocity``, ...)."""
        pts, arcs = grooved_roll_profile(barrel_radius, barrel_width, groove_radius,
                                         groove_depth, flange_height, flange_width,
                                         fillet_radius, s0, edge_radius)
        kwargs.setdefault("name", "roll")
        return cls(pts, arcs, inside=False, **kwargs)


# --------------------------------------------------------------------------------------------
# triangulation
# --------------------------------------------------------------------------------------------

def faceted_revolved(tool: RevolvedProfile, n_theta: int, sector: Optional[Tuple[float, float]]
                     = None, ds: Optional[float] = None, max_angle: float = np.radians(10.0),
                     extension: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """Triangulate the surface of a :class:`RevolvedProfile` (whole or a sector).

    The profile is divided at its points (every kink circle is a ring of mesh vertices), lines
    into pieces no longer than ``ds`` (one piece if ``ds`` is None), arcs into pieces of at most
    ``max_angle`` (and ``ds``); the straight extensions of open ends are meshed over the length
    ``extension`` (0: not at all). Every vertex lies on the exact surface. Angles are measured
    about the axis from :attr:`RevolvedProfile.e_fixed` towards ``axis × e_fixed``; each ring
    has ``n_theta`` equal angular divisions over the meshed range. A profile point on the axis
    becomes a single vertex (a fan of triangles).

    Each quad cell of the (profile, θ) grid is split along a diagonal whose direction is
    mirrored about the mid-angle of the meshed range (cells in the first half one way, in the
    second half the other way; the middle column of an odd ``n_theta`` is split in four
    triangles around a centre vertex placed on the exact surface), so a **sector mesh is
    mirror-symmetric about its mid-plane** (and about the plane through its edges' mid-angle
    for the whole turn).

    Triangles are oriented counter-clockwise about the normal pointing to free space, as
    :class:`~fxcontact.tools.faceted.FacetedTool` expects. The vertices are in the tool's
    reference frame; give the faceted tool the same motion (e.g.
    ``MovedTool(FacetedTool(V, T), tool.motion)``). A closed cavity (``inside=True`` with both
    profile ends on the axis) gives a closed mesh oriented inwards, which ``FacetedTool``
    rejects (it takes closed surfaces as the boundary of the tool).

    Args:
        tool: the analytic tool.
        n_theta: angular divisions of the meshed range (>= 3 for the whole turn, >= 1 for a
            sector).
        sector: ``(θ0, θ1)`` in radians with ``0 < θ1 − θ0 < 2π``, or None for the whole turn.
        ds: maximum length of a meridian edge (None: straight segments are not divided).
        max_angle: maximum angle of an arc piece (radians).
        extension: length of the meshed part of each straight end extension.

    Returns:
        ``(vertices (N, 3), triangles (M, 3))``.
    """
    if not isinstance(tool, RevolvedProfile):
        raise ValueError(f"tool must be a RevolvedProfile, got {type(tool).__name__}")
    try:
        nt = int(n_theta)
    except (TypeError, ValueError):
        raise ValueError(f"n_theta must be an integer, got {n_theta!r}") from None
    if nt != n_theta:
        raise ValueError(f"n_theta must be an integer, got {n_theta!r}")
    if sector is None:
        if nt < 3:
            raise ValueError(f"n_theta must be >= 3 for the whole turn, got {nt}")
        th0, th1, periodic = 0.0, 2 * np.pi, True
    else:
        try:
            th0, th1 = (float(v) for v in sector)
        except (TypeError, ValueError):
            raise ValueError(f"sector must be (theta0, theta1), got {sector!r}") from None
        if not (np.isfinite(th0) and np.isfinite(th1) and 0 < th1 - th0 < 2 * np.pi):
            raise ValueError(f"sector must satisfy 0 < θ1 − θ0 < 2π, got {sector!r}")
        if nt < 1:
            raise ValueError(f"n_theta must be >= 1, got {nt}")
        periodic = False
    if ds is not None:
        ds = positive_number(ds, "ds")
    max_angle = positive_number(max_angle, "max_angle")
    extension = positive_number(extension, "extension", allow_zero=True)
    prof = tool.profile
    # meridian nodes: list of (s, ρ); cells between consecutive nodes, with their midpoints
    nodes: List[np.ndarray] = []
    mids: List[np.ndarray] = []

    def add_piece(pts_fn, m):
        f = np.linspace(0.0, 1.0, m + 1)
        for k in range(m):
            if not nodes:
                nodes.append(pts_fn(f[k]))
            mids.append(pts_fn(0.5 * (f[k] + f[k + 1])))
            nodes.append(pts_fn(f[k + 1]))

    def nsub(length):
        return 1 if ds is None else max(1, int(math.ceil(length / ds - 1e-9)))

    for p in prof.prims:
        if p.kind == ARC:
            m = max(nsub(p.r * abs(p.delta)), int(math.ceil(abs(p.delta) / max_angle - 1e-9)))
            add_piece(p.point, m)
            continue
        # pieces: [-extension, 0] backward extension, [0, length] the profile segment,
        # [length, length + extension] forward extension (tangent rays have length 0)
        parts = []
        if not np.isfinite(p.tlo) and extension > 0:
            parts.append((-extension, 0.0))
        if p.length > 0:
            parts.append((0.0, p.length))
        if not np.isfinite(p.thi) and extension > 0:
            parts.append((p.length, p.length + extension))
        for a_, b_ in parts:
            add_piece(lambda f, a_=a_, b_=b_, p=p: p.A0 + (a_ + f * (b_ - a_)) * p.u,
                      nsub(b_ - a_))
    nodes_a = np.array(nodes)
    # the profile points exactly (arc end points are recomputed with rounding errors)
    for pp in prof.points:
        near = np.hypot(*(nodes_a - pp).T) <= SNAP_TOL * prof.L
        nodes_a[near] = pp
    mids_a = np.array(mids)
    w = tool.axis
    e1 = tool.e_fixed
    e2 = np.cross(w, e1)
    nring = nt if periodic else nt + 1
    th = th0 + (th1 - th0) * np.arange(nring) / nt
    V: List[np.ndarray] = []
    ring_start = []
    for s, rho in nodes_a:
        ring_start.append(len(V))
        if rho == 0.0:
            V.append(tool.axis_point + s * w)
        else:
            for t in th:
                V.append(tool.axis_point + s * w + rho * (math.cos(t) * e1 + math.sin(t) * e2))
    T: List[Tuple[int, int, int]] = []

    def vid(k, j):
        if nodes_a[k, 1] == 0.0:
            return ring_start[k]
        return ring_start[k] + (j % nt if periodic else j)

    for k in range(len(nodes_a) - 1):
        for j in range(nt):
            a_, b_ = vid(k, j), vid(k + 1, j)
            c_, d_ = vid(k + 1, j + 1), vid(k, j + 1)
            if a_ == d_:  # node k on the axis
                T.append((a_, b_, c_))
            elif b_ == c_:  # node k + 1 on the axis
                T.append((a_, b_, d_))
            elif 2 * j + 1 == nt:  # middle column of an odd count: 4 triangles
                s, rho = mids_a[k]
                tm = th0 + (th1 - th0) * (j + 0.5) / nt
                x = len(V)
                V.append(tool.axis_point + s * w
                              + rho * (math.cos(tm) * e1 + math.sin(tm) * e2))
                T.extend([(a_, b_, x), (b_, c_, x), (c_, d_, x), (d_, a_, x)])
            elif 2 * j + 1 < nt:
                T.extend([(a_, b_, c_), (a_, c_, d_)])
            else:
                T.extend([(a_, b_, d_), (b_, c_, d_)])
    Va = np.array(V, dtype=np.float64)
    Ta = np.array(T, dtype=np.int64)
    # the (profile, θ) orientation has its normal on the right of the profile direction:
    # free space is there iff the tool is on the left
    if prof.lam < 0:
        Ta = Ta[:, [0, 2, 1]]
    return Va, Ta
