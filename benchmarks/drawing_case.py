"""A test-size wire-drawing case: a Norton–Hoff quarter bar pulled through a smooth conical die.

Used by ``bench_newton_rigid_plastic.py`` and by the tests of Newton on nearly rigid-plastic
materials. The die is a surface of revolution about the z axis (drawing direction +z): an
infinite conical entry of semi-angle α, a circular fillet of radius ``fillet`` tangent to the cone
and to the bearing, and a cylindrical bearing of radius R_f = R₀ √(1 − reduction) (C¹ profile,
so no node slides over an edge). The bar is meshed already shaped by the die: radius R₀
upstream, the die's profile in the die, R_f downstream (the drawn nose). It is pulled by the
prescribed axial velocity of its front face; the back face is free (no back tension), the two
symmetry planes x = 0 and y = 0 carry the symmetry conditions, the lateral surface is in
frictionless implicit penalty contact with the die.
"""

from __future__ import annotations

import math
from typing import Dict, Optional

import numpy as np
from mpi4py import MPI

from fxcontact.tools.base import Projection, RigidMotion, Tool, as_points

__all__ = ["DrawingDie", "drawing_bar", "DRAWING_TAGS", "drawing_simulation",
           "mean_strain_rate"]

#: facet tags of :func:`drawing_bar`
DRAWING_TAGS: Dict[str, int] = {"back": 1, "front": 2, "lateral": 3, "symmetry_x": 4,
                                "symmetry_y": 5}


class DrawingDie(Tool):
    """Static drawing die about the z axis: conical entry, fillet, bearing (numpy).

    In the meridian half-plane (s = z, ρ = distance to the axis) the free space is
    ρ < R(s); the bearing (ρ = R_f) starts at ``s = z_bearing``. The signed distance is the
    distance to the C¹ profile (segment, arc, half-line), positive on the axis side.

    Args:
        exit_radius: R_f.
        half_angle: cone semi-angle α [rad].
        z_bearing: axial position where the fillet meets the bearing.
        fillet: radius of the fillet between cone and bearing (> 0).
    """

    has_hessian = False

    def __init__(self, exit_radius: float, half_angle: float, z_bearing: float, fillet: float,
                 name: str = "die"):
        if not (exit_radius > 0 and fillet > 0 and 0 < half_angle < 0.5 * math.pi):
            raise ValueError("DrawingDie needs exit_radius > 0, fillet > 0, 0 < α < π/2")
        self.Rf, self.alpha, self.z1, self.Rc = (float(exit_radius), float(half_angle),
                                                 float(z_bearing), float(fillet))
        self.motion = RigidMotion()
        self.name = name
        a = self.alpha
        self.center = np.array([self.z1, self.Rf + self.Rc])            # fillet centre (s, ρ)
        self.tangent_point = self.center + self.Rc * np.array([-math.sin(a), -math.cos(a)])

    def radius(self, s):
        """R(s), the die radius at axial positions s."""
        s = np.asarray(s, float)
        a, (sc, rc), (st, rt) = self.alpha, self.center, self.tangent_point
        cone = rt - (s - st) * math.tan(a)
        arc = rc - np.sqrt(np.maximum(self.Rc**2 - (s - sc) ** 2, 0.0))
        return np.where(s <= st, cone, np.where(s < self.z1, arc, self.Rf))

    def entry_position(self, radius: float) -> float:
        """Axial position where the cone's radius equals ``radius`` (≥ the tangent point's)."""
        st, rt = self.tangent_point
        return st - (radius - rt) / math.tan(self.alpha)

    def _project_reference(self, y: np.ndarray, hessian: bool) -> Projection:
        y = as_points(y)
        n = len(y)
        a = self.alpha
        rho = np.hypot(y[:, 0], y[:, 1])
        flag = np.where(rho <= 1e-12 * self.Rf, 2, 0).astype(np.int32)
        er = np.zeros((n, 2))
        er[:, 0] = 1.0
        ok = rho > 1e-12 * self.Rf
        er[ok] = y[ok, :2] / rho[ok, None]
        P = np.stack([y[:, 2], rho], axis=1)
        # candidate closest points and free-side normals on the three pieces
        tdir = np.array([math.cos(a), -math.sin(a)])
        T = self.tangent_point
        u = np.minimum((P - T) @ tdir, 0.0)
        QL = T + u[:, None] * tdir
        nL = np.broadcast_to(np.array([-math.sin(a), -math.cos(a)]), (n, 2))
        dC = P - self.center
        th = np.clip(np.arctan2(dC[:, 0], -dC[:, 1]), -a, 0.0)
        nA = np.stack([np.sin(th), -np.cos(th)], axis=1)
        QA = self.center + self.Rc * nA
        QB = np.stack([np.maximum(P[:, 0], self.z1), np.full(n, self.Rf)], axis=1)
        nB = np.broadcast_to(np.array([0.0, -1.0]), (n, 2))
        Q = np.stack([QL, QA, QB])
        N = np.stack([nL, nA, nB])
        dist = np.linalg.norm(P[None] - Q, axis=2)
        k = np.argmin(dist, axis=0)
        idx = np.arange(n)
        q, nn = Q[k, idx], N[k, idx]
        gap = np.einsum("ni,ni->n", P - q, nn)
        normal = np.zeros((n, 3))
        normal[:, :2] = nn[:, 1:2] * er
        normal[:, 2] = nn[:, 0]
        point = y - gap[:, None] * normal
        return Projection(gap, normal, point, None, np.zeros(n, np.int64), flag)


def drawing_bar(comm, R0: float, die: DrawingDie, upstream: float, nose: float, h: float,
                h_die: Optional[float] = None):
    """Quarter bar (x ≥ 0, y ≥ 0) shaped by ``die``: radius R₀ from ``upstream`` before the
    cone entry, the die profile, then the bearing radius over ``nose``. Element size ``h_die``
    around the die (default h), ``h`` elsewhere. Returns ``(mesh, cell_tags, facet_tags)``
    with :data:`DRAWING_TAGS`."""
    from fxcontact.meshing import gmsh_model_mesh, gmsh_session

    if not (R0 > die.Rf and upstream > 0 and nose > 0 and h > 0):
        raise ValueError("drawing_bar needs R0 > exit radius and upstream, nose, h > 0")
    h_die = h if h_die is None else h_die
    z_in = die.entry_position(R0)
    if z_in > die.tangent_point[0]:
        raise ValueError("R0 is too small for this die (the bar would not reach the cone)")
    zb, zf = z_in - upstream, die.z1 + nose
    with gmsh_session("drawing_bar") as gmsh:
        if comm.rank == 0:
            occ = gmsh.model.occ
            (st, rt), (sc, rc) = die.tangent_point, die.center
            pts = [occ.addPoint(0, 0, zb), occ.addPoint(R0, 0, zb), occ.addPoint(R0, 0, z_in),
                   occ.addPoint(rt, 0, st), occ.addPoint(die.Rf, 0, die.z1),
                   occ.addPoint(die.Rf, 0, zf), occ.addPoint(0, 0, zf)]
            c = occ.addPoint(rc, 0, sc)
            lines = [occ.addLine(pts[0], pts[1]), occ.addLine(pts[1], pts[2]),
                     occ.addLine(pts[2], pts[3]), occ.addCircleArc(pts[3], c, pts[4]),
                     occ.addLine(pts[4], pts[5]), occ.addLine(pts[5], pts[6]),
                     occ.addLine(pts[6], pts[0])]
            s = occ.addPlaneSurface([occ.addCurveLoop(lines)])
            occ.revolve([(2, s)], 0, 0, 0, 0, 0, 1, 0.5 * math.pi)
            occ.remove([(2, s)], recursive=False)
            occ.synchronize()
            vols = gmsh.model.getEntities(3)
            gmsh.model.addPhysicalGroup(3, [v[1] for v in vols], 1)
            groups = {k: [] for k in DRAWING_TAGS}
            eps = 1e-6 * R0
            for dim, tag in gmsh.model.getEntities(2):
                cm = np.array(occ.getCenterOfMass(dim, tag))
                if abs(cm[2] - zb) < eps:
                    groups["back"].append(tag)
                elif abs(cm[2] - zf) < eps:
                    groups["front"].append(tag)
                elif abs(cm[0]) < eps:
                    groups["symmetry_x"].append(tag)
                elif abs(cm[1]) < eps:
                    groups["symmetry_y"].append(tag)
                else:
                    groups["lateral"].append(tag)
            for name, tags in groups.items():
                gmsh.model.addPhysicalGroup(2, tags, DRAWING_TAGS[name])
            f = gmsh.model.mesh.field
            bx = f.add("Box")
            f.setNumber(bx, "VIn", h_die)
            f.setNumber(bx, "VOut", h)
            f.setNumber(bx, "XMin", -1.0)
            f.setNumber(bx, "XMax", 2 * R0)
            f.setNumber(bx, "YMin", -1.0)
            f.setNumber(bx, "YMax", 2 * R0)
            f.setNumber(bx, "ZMin", z_in - 0.5 * R0)
            f.setNumber(bx, "ZMax", die.z1 + 0.5 * R0)
            f.setNumber(bx, "Thickness", 0.5 * R0)
            f.setAsBackgroundMesh(bx)
            gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
            gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
            gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
            gmsh.model.mesh.generate(3)
        return gmsh_model_mesh(gmsh, comm, 3)


def mean_strain_rate(R0: float, reduction: float, half_angle: float, entry_speed: float) -> float:
    """Mean equivalent strain rate in a conical die (THEORY §14.2) for a reduction of area:
    :func:`fxcontact.theory.forming.drawing_mean_strain_rate` with R_f = R₀ √(1 − reduction)."""
    from fxcontact.theory.forming import drawing_mean_strain_rate

    return drawing_mean_strain_rate(R0, R0 * math.sqrt(1.0 - reduction), half_angle,
                                    entry_speed)


def drawing_simulation(comm=MPI.COMM_WORLD, R0: float = 5.0, reduction: float = 0.15,
                       half_angle_deg: float = 10.0, fillet: float = 4.0, h: float = 1.2,
                       h_die: float = 0.6, upstream: float = 4.0, nose: float = 3.0,
                       K: float = 445.0, m: float = 0.016, regularization: float = 1e-6,
                       speed: float = 10.0, scheme: str = "implicit", beta: float = 1e3,
                       sticky_gap: float = 0.0, solver_options=None, quadrature_degree=None):
    """The drawing :class:`~fxcontact.simulation.Simulation` (not yet run), its die and its
    contact contributor. Units: mm, s, MPa; ``speed`` is the pulling speed of the front face;
    ``quadrature_degree`` of the MINI space (None: the library's default)."""
    from fxcontact.contact.boundary import ContactBoundary
    from fxcontact.contact.nodal import NodalContact
    from fxcontact.materials import NortonHoff
    from fxcontact.simulation import Simulation
    from fxcontact.spaces import MixedSpace

    Rf = R0 * math.sqrt(1.0 - reduction)
    die = DrawingDie(Rf, math.radians(half_angle_deg), z_bearing=0.0, fillet=fillet)
    msh, _, ft = drawing_bar(comm, R0, die, upstream, nose, h, h_die)
    space = MixedSpace(msh, quadrature_degree=quadrature_degree)
    sim = Simulation(space, NortonHoff(K=K, m=m, regularization=regularization),
                     solver_options=solver_options, progress=False)
    f = {k: sim.facets(ft, v) for k, v in DRAWING_TAGS.items()}
    sim.add_velocity_bc(f["symmetry_x"], 0.0, component=0)
    sim.add_velocity_bc(f["symmetry_y"], 0.0, component=1)
    sim.add_velocity_bc(f["front"], speed, component=2)
    sim.add_reaction("front", f["front"])
    # penalty ρ = β η / h_e at the die's mean strain rate (the start-up guess is rigid)
    rate = mean_strain_rate(R0, reduction, die.alpha, speed * (1.0 - reduction))
    contact = NodalContact(ContactBoundary(space, ft, DRAWING_TAGS["lateral"]), die,
                           scheme=scheme, beta=beta, strain_rate=rate, element_size=h_die,
                           sticky_gap=sticky_gap)
    sim.add_contributor(contact)
    return sim, die, contact
