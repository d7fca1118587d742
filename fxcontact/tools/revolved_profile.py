"""Meridian profiles of a :class:`~fxcontact.tools.revolved.RevolvedProfile`: the 2-D geometry
of lines and circular arcs in the ``(s, ρ)`` half-plane, the checked profile (ends, kinks,
self-intersections, the side of the tool; see :mod:`fxcontact.tools.revolved`) and the two
standard profiles, :func:`die_profile` and :func:`grooved_roll_profile`."""

from __future__ import annotations

import math
from typing import List

import numpy as np

__all__ = ["die_profile", "grooved_roll_profile", "Profile", "positive_number", "LINE", "ARC",
           "SNAP_TOL"]

#: kinds of the profile's primitives: a straight segment, a circular arc
LINE, ARC = 0, 1
#: Relative tolerance (of the profile size) for snapping ρ to 0 and for degenerate segments.
SNAP_TOL = 1e-12


# --------------------------------------------------------------------------------------------
# 2-D geometry helpers
# --------------------------------------------------------------------------------------------

def _left(v) -> np.ndarray:
    """Left normal (rotation by +90°) of a 2-D vector in the (s, ρ) plane."""
    return np.array([-v[1], v[0]])


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


class _Seg:
    """One primitive of the profile: a line piece or a circular arc.

    Lines: origin ``A0``, unit direction ``u``, parameter range ``[tlo, thi]`` (infinite for an
    extended end), ``length`` of the finite profile part ``[0, length]``. Arcs: centre ``o``,
    radius ``r``, unit start direction ``a0`` from the centre, signed sweep ``delta`` (> 0
    counter-clockwise). ``ta``/``tb``: unit tangents at the start and end, in the profile
    direction."""

    def __init__(self, kind, feature, label):
        self.kind = kind
        self.feature = feature
        self.label = label

    @classmethod
    def line(cls, A0, u, tlo, thi, feature, label):
        s = cls(LINE, feature, label)
        s.A0, s.u, s.tlo, s.thi = np.asarray(A0, float), np.asarray(u, float), tlo, thi
        s.length = float(thi) if np.isfinite(thi) else 0.0  # finite part [0, length]
        s.ta = s.tb = s.u
        return s

    @classmethod
    def arc(cls, o, r, a0, delta, feature, label):
        s = cls(ARC, feature, label)
        s.o, s.r, s.a0, s.delta = np.asarray(o, float), float(r), np.asarray(a0, float), delta
        sg = 1.0 if delta > 0 else -1.0
        b0 = s.direction(1.0)
        s.ta = sg * _left(s.a0)
        s.tb = sg * _left(b0)
        return s

    def direction(self, f: float) -> np.ndarray:
        """Unit direction from the centre at the fraction f of the sweep (arcs)."""
        c, sn = math.cos(f * self.delta), math.sin(f * self.delta)
        return np.array([c * self.a0[0] - sn * self.a0[1], sn * self.a0[0] + c * self.a0[1]])

    def point(self, f: float) -> np.ndarray:
        """Point at the fraction f ∈ [0, 1] (arcs) or the parameter f (lines)."""
        if self.kind == ARC:
            return self.o + self.r * self.direction(f)
        return self.A0 + f * self.u

    def contains_angle(self, p, strict=True) -> bool:
        """Arc: whether the direction of p from the centre lies within the sweep."""
        e = (np.asarray(p) - self.o)
        beta = math.atan2(_cross(self.a0, e), float(self.a0 @ e))
        if self.delta > 0:
            return 0.0 < beta < self.delta if strict else -1e-12 <= beta <= self.delta + 1e-12
        return self.delta < beta < 0.0 if strict else self.delta - 1e-12 <= beta <= 1e-12


def _line_line(p: _Seg, q: _Seg, tol: float):
    """Intersection points of two (possibly infinite) line pieces; collinear overlaps are
    reported by sample points of the overlap."""
    c = _cross(p.u, q.u)
    d = q.A0 - p.A0
    if abs(c) > 1e-14:
        t = _cross(d, q.u) / c
        u = _cross(d, p.u) / c
        if p.tlo - tol <= t <= p.thi + tol and q.tlo - tol <= u <= q.thi + tol:
            return [p.A0 + t * p.u]
        return []
    if abs(_cross(d, p.u)) > tol:
        return []  # parallel, distinct lines
    # collinear: parameter range of q on p's line
    a = float(d @ p.u)
    sgn = float(q.u @ p.u)
    lo, hi = sorted((a + sgn * q.tlo, a + sgn * q.thi))
    lo, hi = max(lo, p.tlo), min(hi, p.thi)
    if lo > hi + tol:
        return []
    if not np.isfinite(lo):
        lo = hi - 1.0
    if not np.isfinite(hi):
        hi = lo + 1.0
    return [p.A0 + lo * p.u, p.A0 + 0.5 * (lo + hi) * p.u, p.A0 + hi * p.u]


def _line_arc(p: _Seg, a: _Seg, tol: float):
    d = p.A0 - a.o
    b = float(d @ p.u)
    cc = float(d @ d) - a.r**2
    disc = b * b - cc
    if disc < -tol * a.r:
        return []
    sq = math.sqrt(max(disc, 0.0))
    out = []
    for t in (-b - sq, -b + sq):
        if p.tlo - tol <= t <= p.thi + tol:
            x = p.A0 + t * p.u
            if a.contains_angle(x, strict=False):
                out.append(x)
    return out


def _arc_arc(p: _Seg, q: _Seg, tol: float):
    d = q.o - p.o
    dist = float(np.hypot(*d))
    if dist <= tol and abs(p.r - q.r) <= tol:
        # same circle: overlapping sweeps?
        out = []
        for f in (0.0, 0.5, 1.0):
            x = q.point(f)
            if p.contains_angle(x, strict=True):
                out.append(x)
            y = p.point(f)
            if q.contains_angle(y, strict=True):
                out.append(y)
        return out
    if dist > p.r + q.r + tol or dist < abs(p.r - q.r) - tol or dist <= tol:
        return []
    a = (p.r**2 - q.r**2 + dist**2) / (2 * dist)
    h = math.sqrt(max(p.r**2 - a * a, 0.0))
    m = p.o + a * d / dist
    n = _left(d / dist)
    out = []
    for x in (m + h * n, m - h * n):
        if p.contains_angle(x, strict=False) and q.contains_angle(x, strict=False):
            out.append(x)
    return out


def _intersections(p: _Seg, q: _Seg, tol: float):
    if p.kind == LINE and q.kind == LINE:
        return _line_line(p, q, tol)
    if p.kind == LINE:
        return _line_arc(p, q, tol)
    if q.kind == LINE:
        return _line_arc(q, p, tol)
    return _arc_arc(p, q, tol)


# --------------------------------------------------------------------------------------------
# profile construction and checks
# --------------------------------------------------------------------------------------------

class Profile:
    """Checked profile: primitives and vertices in the (s, ρ) plane (see RevolvedProfile)."""

    def __init__(self, points, arcs, inside: bool):
        P = np.asarray(points, dtype=np.float64) if not isinstance(points, np.ndarray) \
            else points.astype(np.float64)
        if P.ndim != 2 or P.shape[1] != 2 or P.shape[0] < 2:
            raise ValueError(f"profile points must have shape (n + 1 >= 2, 2) as (s, ρ) pairs, "
                             f"got {np.shape(points)}")
        if not np.all(np.isfinite(P)):
            bad = np.flatnonzero(~np.all(np.isfinite(P), axis=1))
            raise ValueError(f"profile points {bad[:10].tolist()} are not finite")
        n = P.shape[0] - 1
        L = float(max(np.ptp(P[:, 0]), np.ptp(P[:, 1]), np.max(np.abs(P[:, 1]))))
        if not L > 0.0:
            raise ValueError("profile points are all equal")
        self.L = L
        tol = SNAP_TOL * L
        neg = np.flatnonzero(P[:, 1] < -tol)
        if neg.size:
            raise ValueError(f"profile point {int(neg[0])} has ρ = {P[neg[0], 1]:.6g} < 0: the "
                             f"profile lies in the half-plane ρ >= 0")
        P[:, 1] = np.where(P[:, 1] <= tol, 0.0, P[:, 1])
        on_axis = P[:, 1] == 0.0
        mid = np.flatnonzero(on_axis[1:-1]) + 1
        if mid.size:
            raise ValueError(f"profile point {int(mid[0])} lies on the axis (ρ = 0): only the "
                             f"first and last points may")
        # arcs
        if arcs is None:
            radii = [None] * n
        else:
            radii = list(arcs)
            if len(radii) != n:
                raise ValueError(f"arcs must give one entry (None for a line, signed radius for "
                                 f"an arc) per segment: {n} segments, got {len(radii)}")
        # side: direction of increasing s between the end points
        ds = P[-1, 0] - P[0, 0]
        if abs(ds) <= 1e-9 * L:
            raise ValueError("the first and last profile points have the same s: cannot tell "
                             "the tool side (the profile must advance along the axis)")
        self.inside = bool(inside)
        D = 1.0 if ds > 0 else -1.0
        #: +1: the tool is on the left of the profile as given, −1: on the right
        self.lam = D if inside else -D
        self.points = P
        self.n = n
        self.on_axis = on_axis
        segs: List[_Seg] = []
        for i in range(n):
            A, B = P[i], P[i + 1]
            c = float(np.hypot(*(B - A)))
            if c <= tol:
                raise ValueError(f"segment {i} (points {i} -> {i + 1}) has zero length")
            if on_axis[i] and on_axis[i + 1] and radii[i] in (None, 0, 0.0):
                raise ValueError(f"segment {i} lies on the axis")
            R = radii[i]
            if R is None or R == 0:
                u = (B - A) / c
                segs.append(_Seg.line(A, u, 0.0, c, i, f"segment {i} (line)"))
                continue
            try:
                R = float(R)
            except (TypeError, ValueError):
                raise ValueError(f"segment {i}: arc radius must be a number or None, "
                                 f"got {R!r}") from None
            if not np.isfinite(R):
                raise ValueError(f"segment {i}: arc radius must be finite, got {R!r}")
            r = abs(R)
            if r < 0.5 * c * (1 - 1e-12):
                raise ValueError(f"segment {i}: arc radius {r:.6g} is smaller than half its "
                                 f"chord {0.5 * c:.6g} (points {i} -> {i + 1})")
            h = math.sqrt(max(r * r - 0.25 * c * c, 0.0))
            u = (B - A) / c
            sg = 1.0 if R > 0 else -1.0
            o = 0.5 * (A + B) + sg * h * _left(u)
            if abs(o[1]) <= tol:
                o[1] = 0.0  # centred on the axis (sphere-like): regular on the axis
            a0 = (A - o) / r
            half = math.asin(min(1.0, 0.5 * c / r))
            seg = _Seg.arc(o, r, a0, sg * 2.0 * half, i, f"segment {i} (arc)")
            # lowest ρ reached inside the sweep (direction −e_ρ)
            low = o - np.array([0.0, r])  # lowest point of the circle
            if (o[1] - r <= tol and seg.contains_angle(low, strict=True)
                    and min(np.hypot(*(low - A)), np.hypot(*(low - B))) > 1e-9 * L):
                raise ValueError(f"segment {i}: the arc reaches the axis between its end points "
                                 f"(lowest ρ = {o[1] - r:.6g})")
            segs.append(seg)
        self.segs = segs
        # ends: on the axis, or extended by the tangent ray
        extra = []
        first, last = segs[0], segs[-1]
        for end, seg, t, name in ((0, first, first.ta, "first"), (n, last, last.tb, "last")):
            out = -t if end == 0 else t  # direction leaving the profile at this end
            if on_axis[end]:
                if -out[1] <= 1e-9:
                    raise ValueError(f"the {name} profile point is on the axis but the profile "
                                     f"does not leave the axis there (tangent ρ-component "
                                     f"{-out[1]:.3g} <= 0)")
                continue
            if out[1] < -1e-12:
                raise ValueError(f"the {name} profile point's tangent extension would approach "
                                 f"the axis (direction {out.round(6).tolist()}): end the profile "
                                 f"on the axis or extend it yourself")
            if seg.kind == LINE:
                if end == 0:
                    seg.tlo = -np.inf
                else:
                    seg.thi = np.inf
            else:
                fid = 2 * n + 1 if end == 0 else 2 * n + 2
                lbl = f"tangent extension of the {name} point (point {end})"
                ray = _Seg.line(P[end], t, -np.inf if end == 0 else 0.0,
                                0.0 if end == 0 else np.inf, fid, lbl)
                extra.append((end, ray))
        self.rays = extra
        # cusps and vertices
        prims = ([r for e, r in extra if e == 0] + segs + [r for e, r in extra if e == n])
        self.prims = prims
        verts = []
        for i in range(n + 1):
            if 0 < i < n:
                t_in, t_out = segs[i - 1].tb, segs[i].ta
                if float(t_in @ t_out) < -1 + 1e-12:
                    raise ValueError(f"the profile reverses its direction at point {i} (cusp)")
                nu_in, nu_out = self.nu(t_in), self.nu(t_out)
                m = nu_in + nu_out
                m = m / np.hypot(*m)
                kink = abs(_cross(t_in, t_out)) > 1e-12 or float(t_in @ t_out) < 0
                verts.append((i, m, kink))
            else:
                seg = segs[0] if i == 0 else segs[-1]
                t = seg.ta if i == 0 else seg.tb
                nu = self.nu(t)
                if on_axis[i]:
                    m = np.array([math.copysign(1.0, nu[0]), 0.0])
                    verts.append((i, m, abs(nu[1]) > 1e-12))
                elif seg.kind == ARC:
                    verts.append((i, nu, False))  # tangent junction with the extension
        self.verts = verts
        self._check_intersections()

    def nu(self, t) -> np.ndarray:
        """Free-side unit normal for the unit tangent t (profile direction)."""
        return -self.lam * _left(t)

    def _check_intersections(self):
        prims, L = self.prims, self.L
        tol = 1e-10 * L
        near = 1e-7 * L
        for a in range(len(prims)):
            for b in range(a + 1, len(prims)):
                p, q = prims[a], prims[b]
                shared = None
                if b == a + 1:
                    shared = p.point(1.0) if p.kind == ARC else p.A0 + p.thi * p.u
                pts = _intersections(p, q, tol)
                for x in pts:
                    if shared is not None and np.hypot(*(x - shared)) <= near:
                        continue
                    raise ValueError(f"the profile intersects itself: {p.label} and {q.label} "
                                     f"meet at (s, ρ) = ({x[0]:.6g}, {x[1]:.6g})")

    def arrays(self):
        """Kernel data: kinds (K,), features (K,), primitive data (K, 10), vertex data (J, 5),
        vertex features (J,)."""
        K = len(self.prims)
        kind = np.zeros(K, np.int64)
        feat = np.zeros(K, np.int64)
        data = np.zeros((K, 10))
        for k, p in enumerate(self.prims):
            kind[k] = p.kind
            feat[k] = p.feature
            if p.kind == LINE:
                nu = self.nu(p.u)
                data[k, :8] = [p.A0[0], p.A0[1], p.u[0], p.u[1], p.tlo, p.thi, nu[0], nu[1]]
            else:
                sg = 1.0 if p.delta > 0 else -1.0
                kap = self.lam * sg  # tool on the centre side (left turn with tool on the left)
                mid = p.direction(0.5)
                data[k] = [p.o[0], p.o[1], p.r, kap, p.a0[0], p.a0[1], p.delta, mid[0], mid[1],
                           1.0 if p.o[1] == 0.0 else 0.0]
        J = len(self.verts)
        vdata = np.zeros((J, 5))
        vfeat = np.zeros(J, np.int64)
        for j, (i, m, kink) in enumerate(self.verts):
            vdata[j] = [self.points[i, 0], self.points[i, 1], m[0], m[1], 1.0 if kink else 0.0]
            vfeat[j] = self.n + i
        return kind, feat, np.ascontiguousarray(data), np.ascontiguousarray(vdata), vfeat


# --------------------------------------------------------------------------------------------
# standard profiles
# --------------------------------------------------------------------------------------------

def positive_number(v, name, allow_zero=False) -> float:
    """``v`` as a finite float > 0 (>= 0 with ``allow_zero``); ValueError naming ``name``
    otherwise."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {v!r}") from None
    if not np.isfinite(x) or x < 0 or (x == 0 and not allow_zero):
        raise ValueError(f"{name} must be finite and {'>= 0' if allow_zero else '> 0'}, "
                         f"got {v!r}")
    return x


def die_profile(entry_radius, exit_radius, half_angle, land_length, fillet_radius=0.0,
                relief_angle=None, relief_length=0.0, s0=0.0):
    """Profile of a drawing die, the wire moving towards +s: ``(points, arcs)``.

    Entry cone of semi-angle α from ``(s0, entry_radius)`` down to the exit (bearing) radius
    ``R_f``, an optional fillet arc of radius ``fillet_radius`` tangent to the cone and to the
    land, the cylindrical bearing land of length ``land_length`` (measured from the fillet's
    tangent point, or from the cone–land corner without fillet) at ``R_f``, and an optional exit
    relief cone of semi-angle ``relief_angle`` and axial length ``relief_length`` (a sharp kink
    at the land's end). As for every :class:`RevolvedProfile`, the entry cone is continued
    backwards and the last segment (land or relief) forwards to infinity.

    Args:
        entry_radius: radius at the start of the entry cone (> exit radius).
        exit_radius: bearing radius ``R_f > 0``.
        half_angle: cone semi-angle α (radians, 0 < α < π/2).
        land_length: bearing length ``> 0``.
        fillet_radius: radius of the cone–land fillet (0: sharp corner).
        relief_angle: exit relief semi-angle (radians, 0 < β <= π/2), or None for no relief.
        relief_length: axial length of the relief (> 0 if ``relief_angle`` is given; for
            β = π/2 it is its radial height instead).
        s0: axial position of the entry.

    Returns:
        ``(points (n + 1, 2), arcs list)`` for ``RevolvedProfile(points, arcs, inside=True)``.
    """
    Re = positive_number(entry_radius, "entry_radius")
    Rf = positive_number(exit_radius, "exit_radius")
    al = positive_number(half_angle, "half_angle")
    Ll = positive_number(land_length, "land_length")
    rf = positive_number(fillet_radius, "fillet_radius", allow_zero=True)
    s0 = float(s0)
    if not Re > Rf:
        raise ValueError(f"entry_radius ({Re}) must be larger than exit_radius ({Rf})")
    if not al < 0.5 * np.pi:
        raise ValueError(f"half_angle must satisfy 0 < α < π/2 (radians), got {half_angle!r}")
    s1 = s0 + (Re - Rf) / math.tan(al)  # cone–land corner
    tl = rf * math.tan(0.5 * al)  # tangent length of the fillet
    if tl >= (Re - Rf) / math.sin(al):
        raise ValueError(f"fillet_radius {rf} is too large for the entry cone (tangent length "
                         f"{tl:.6g} >= cone length {(Re - Rf) / math.sin(al):.6g})")
    pts = [(s0, Re)]
    arcs: list = []
    if rf > 0:
        pts.append((s1 - tl * math.cos(al), Rf + tl * math.sin(al)))
        arcs.append(None)
        pts.append((s1 + tl, Rf))
        arcs.append(rf)  # counter-clockwise: from the cone direction down to the axis direction
        s_land = s1 + tl
    else:
        pts.append((s1, Rf))
        arcs.append(None)
        s_land = s1
    pts.append((s_land + Ll, Rf))
    arcs.append(None)
    if relief_angle is not None:
        be = positive_number(relief_angle, "relief_angle")
        lr = positive_number(relief_length, "relief_length")
        if be > 0.5 * np.pi:
            raise ValueError(f"relief_angle must satisfy 0 < β <= π/2, got {relief_angle!r}")
        if abs(be - 0.5 * np.pi) < 1e-15:
            pts.append((s_land + Ll, Rf + lr))
        else:
            pts.append((s_land + Ll + lr, Rf + lr * math.tan(be)))
        arcs.append(None)
    return np.array(pts), arcs


def grooved_roll_profile(barrel_radius, barrel_width, groove_radius=0.0, groove_depth=0.0,
                         flange_height=0.0, flange_width=0.0, fillet_radius=0.0, s0=0.0,
                         edge_radius=0.0):
    """Profile of a grooved, optionally flanged roll (body outside): ``(points, arcs)``.

    Centred on ``s0``: a barrel of radius ``R_b`` and width ``W`` (from ``s0 − W/2`` to
    ``s0 + W/2``), with an optional circular groove of radius ``r_g`` and depth ``h_g <= r_g``
    centred on ``s0`` (sharp edges on the barrel), and optional flanges: at each side of the
    barrel a radial face rising by ``flange_height`` (joined to the barrel by a fillet of radius
    ``fillet_radius``, tangent to both) and a flange top of width ``flange_width``. Without
    flanges the barrel is continued to infinity on both sides; with flanges the flange tops are.
    ``edge_radius > 0`` rounds the groove's edges: an arc of that radius tangent to the barrel
    and to the groove replaces each sharp edge (the profile is then C¹ across the groove).

    Returns:
        ``(points (n + 1, 2), arcs list)`` for ``RevolvedProfile(points, arcs, inside=False)``.
    """
    Rb = positive_number(barrel_radius, "barrel_radius")
    W = positive_number(barrel_width, "barrel_width")
    rg = positive_number(groove_radius, "groove_radius", allow_zero=True)
    hg = positive_number(groove_depth, "groove_depth", allow_zero=True)
    hf = positive_number(flange_height, "flange_height", allow_zero=True)
    wf = positive_number(flange_width, "flange_width", allow_zero=True)
    rc = positive_number(fillet_radius, "fillet_radius", allow_zero=True)
    re_ = positive_number(edge_radius, "edge_radius", allow_zero=True)
    s0 = float(s0)
    if re_ > 0 and not hg > 0:
        raise ValueError("edge_radius needs a groove (groove_radius and groove_depth > 0)")
    if (hg > 0) != (rg > 0):
        raise ValueError("give both groove_radius and groove_depth (> 0) or neither")
    if hg > rg:
        raise ValueError(f"groove_depth ({hg}) must not exceed groove_radius ({rg})")
    if hg >= Rb:
        raise ValueError(f"groove_depth ({hg}) must be smaller than barrel_radius ({Rb})")
    b = math.sqrt(max(rg * rg - (rg - hg) ** 2, 0.0)) if hg > 0 else 0.0
    if re_ > 0:
        # edge arc: centre (s0 ± be, Rb − re) at the distance rg + re from the groove centre
        # (s0, Rb − hg + rg); tangent to the barrel at s0 ± be, to the groove at ± (ge_s, ge_r)
        be = math.sqrt((rg + re_) ** 2 - (rg + re_ - hg) ** 2)
        k = rg / (rg + re_)
        ge_s, ge_r = k * be, (Rb - hg + rg) + k * ((Rb - re_) - (Rb - hg + rg))
        b = be
    if hf > 0 and not wf > 0:
        raise ValueError("flanges need flange_width > 0")
    if rc > 0 and not hf > 0:
        raise ValueError("fillet_radius needs flanges (flange_height > 0)")
    if rc >= hf and hf > 0:
        raise ValueError(f"fillet_radius ({rc}) must be smaller than flange_height ({hf})")
    if b + rc >= 0.5 * W:
        raise ValueError(f"the groove (half-width {b:.6g}) and the fillets ({rc}) do not fit "
                         f"in the barrel (half-width {0.5 * W})")
    half = 0.5 * W
    pts: list = []
    arcs: list = []

    def add(p, arc=None):
        if pts:
            arcs.append(arc)
        pts.append(p)

    if hf > 0:
        add((s0 - half - wf, Rb + hf))
        add((s0 - half, Rb + hf))
        if rc > 0:
            add((s0 - half, Rb + rc))
            add((s0 - half + rc, Rb), rc)  # counter-clockwise: face down, then barrel along +s
        else:
            add((s0 - half, Rb))
    else:
        add((s0 - half, Rb))
    if hg > 0 and re_ > 0:
        add((s0 - be, Rb))
        add((s0 - ge_s, ge_r), -re_)  # the edge: clockwise, from the barrel into the groove
        add((s0 + ge_s, ge_r), rg)    # the groove: counter-clockwise below its centre
        add((s0 + be, Rb), -re_)
    elif hg > 0:
        add((s0 - b, Rb))
        add((s0 + b, Rb), rg)  # counter-clockwise below its centre
    if hf > 0:
        if rc > 0:
            add((s0 + half - rc, Rb))
            add((s0 + half, Rb + rc), rc)
        else:
            add((s0 + half, Rb))
        add((s0 + half, Rb + hf))
        add((s0 + half + wf, Rb + hf))
    else:
        add((s0 + half, Rb))
    return np.array(pts, dtype=np.float64), arcs
