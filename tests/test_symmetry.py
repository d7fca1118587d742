"""Symmetry planes of any orientation: a full billet, a quarter (axis-aligned planes, velocity
conditions) and thirds (one or two inclined planes, exact projection) give the same upsetting.

The meshes are built so that the three discrete problems are the same: a 15° wedge of the billet
is meshed once, mirrored about its mid-plane into a 30° piece, and the piece is rotated into 12
(full), 4 (a third) or 3 (a quarter) copies. The full mesh is then invariant under the
reflections about every multiple of 15°, so its discrete solution is symmetric about the planes
of the sector models, and a sector model with exact symmetry conditions reproduces it to the
solver tolerance — a much sharper check than a comparison of different meshes.
"""

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx
import dolfinx.mesh

from fxcontact.materials import NortonHoff
from fxcontact.meshing import gmsh_session
from fxcontact.simulation import Simulation
from fxcontact.newton.solver import SolverOptions
from fxcontact.spaces import MixedSpace
from fxcontact.symmetry import SymmetryPlanes

R, H, V_DIE = 10.0, 6.0, 5.0
TAGS = {"bottom": 1, "top": 2, "lateral": 3, "sym0": 4, "sym1": 5}


def _wedge(h):
    """Nodes and tetrahedra of the 15° wedge 0 ≤ θ ≤ 15° (rank 0 only)."""
    with gmsh_session("wedge") as gmsh:
        gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, H, R, angle=np.pi / 12)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * h)
        gmsh.model.mesh.generate(3)
        tags, x, _ = gmsh.model.mesh.getNodes()
        _, et = gmsh.model.mesh.getElementsByType(4)
    pos = np.empty(int(tags.max()) + 1, dtype=np.int64)
    pos[tags.astype(np.int64)] = np.arange(len(tags))
    return x.reshape(-1, 3), pos[et.astype(np.int64)].reshape(-1, 4)


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def sector_mesh(comm, n_pieces, start_deg=0.0, h=5.0):
    """The billet sector [start, start + 30°·n_pieces] made of mirrored-wedge copies, with
    facet tags TAGS (sym0 at θ = start, sym1 at θ = end; none for the full billet)."""
    if comm.rank == 0:
        x, t = _wedge(h)
        b = np.radians(15.0)
        ref = np.array([[np.cos(2 * b), np.sin(2 * b), 0], [np.sin(2 * b), -np.cos(2 * b), 0],
                        [0, 0, 1.0]])
        px = np.vstack([x, x @ ref.T])
        pt = np.vstack([t, t + len(x)])
        xs, ts = [], []
        for k in range(n_pieces):
            xs.append(px @ _rot(np.radians(start_deg + 30.0 * k)).T)
            ts.append(pt + k * len(px))
        X = np.vstack(xs)
        key = np.round(X, 8)
        _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
        X = X[first]
        T = inv[np.vstack(ts)].astype(np.int64)
    else:
        X, T = np.zeros((0, 3)), np.zeros((0, 4), dtype=np.int64)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.tetrahedron, 1))
    msh = dolfinx.mesh.create_mesh(comm, T, X, domain)
    fdim = 2
    full = n_pieces == 12
    a0, a1 = np.radians(start_deg), np.radians(start_deg + 30.0 * n_pieces)
    n0 = np.array([np.sin(a0), -np.cos(a0)])
    n1 = np.array([-np.sin(a1), np.cos(a1)])
    eps = 1e-6 * R
    markers = {
        "bottom": lambda x: np.isclose(x[2], 0.0),
        "top": lambda x: np.isclose(x[2], H),
        "lateral": lambda x: np.abs(np.hypot(x[0], x[1]) - R) < 0.05 * R,
    }
    if not full:
        markers["sym0"] = lambda x: np.abs(n0 @ x[:2]) < eps
        markers["sym1"] = lambda x: np.abs(n1 @ x[:2]) < eps
    idx, val = [], []
    for name, mk in markers.items():
        f = dolfinx.mesh.locate_entities_boundary(msh, fdim, mk)
        idx.append(f)
        val.append(np.full(len(f), TAGS[name], dtype=np.int32))
    idx, val = np.concatenate(idx), np.concatenate(val)
    order = np.argsort(idx, kind="stable")
    ft = dolfinx.mesh.meshtags(msh, fdim, idx[order], val[order])
    normals = {"sym0": np.r_[n0, 0.0], "sym1": np.r_[n1, 0.0]}
    return msh, ft, normals


def upset(comm, n_pieces, start_deg=0.0, n_inc=2, dt=0.1):
    """Sticking-die upsetting of the sector; returns the full-billet die force per increment,
    (initial, final) vertex positions and the simulation."""
    msh, ft, normals = sector_mesh(comm, n_pieces, start_deg)
    space = MixedSpace(msh)
    sim = Simulation(space, NortonHoff(K=50.0, m=0.15, regularization=1e-4), progress=False)
    fac = lambda name: sim.facets(ft, TAGS[name])  # noqa: E731
    sim.add_velocity_bc(fac("bottom"), np.zeros(3))
    sim.add_velocity_bc(fac("top"), np.array([0.0, 0.0, -V_DIE]))
    sim.add_reaction("die", fac("top"))
    if n_pieces != 12:
        sim.add_symmetry_plane(fac("sym0"), normals["sym0"], name="plane0")
        sim.add_symmetry_plane(fac("sym1"), normals["sym1"], name="plane1")
    x0 = space.vertex_positions()
    sim.run(n_inc * dt, dt)
    scale = 12.0 / n_pieces
    forces = [scale * r["die_z"] for r in sim.history]
    own = space.vertex_owned
    return forces, x0[own], space.vertex_positions()[own], sim


def _gather(comm, x0, x1):
    a = np.concatenate(comm.allgather(x0))
    b = np.concatenate(comm.allgather(x1))
    return {tuple(k): v for k, v in zip(np.round(a, 6), b)}


_RUNS = {}


def upset_world(n_pieces, start_deg=0.0):
    """upset() on COMM_WORLD, computed once per module."""
    key = (n_pieces, start_deg)
    if key not in _RUNS:
        _RUNS[key] = upset(MPI.COMM_WORLD, n_pieces, start_deg)
    return _RUNS[key]


@pytest.fixture(scope="module")
def full():
    return upset_world(12)


@pytest.mark.parametrize("n_pieces,start", [(3, 0.0), (4, 0.0), (4, 30.0)],
                         ids=["quarter", "third", "third-two-inclined"])
def test_sector_equals_full(full, n_pieces, start):
    """Die force and deformed shape of the sector models equal the full billet's (1e-7 of the
    force, 1e-8 R of the positions); the inclined planes are satisfied exactly and their
    reaction is normal to them; the quarter, whose planes are coordinate planes, uses velocity
    conditions."""
    comm = MPI.COMM_WORLD
    F_full, x0f, x1f, _ = full
    F, x0, x1, sim = upset_world(n_pieces, start)
    for a, b in zip(F, F_full):
        assert abs(a - b) <= 1e-7 * abs(b), (a, b)
    ref = _gather(comm, x0f, x1f)
    mine = _gather(comm, x0, x1)
    err = max(np.max(np.abs(v - ref[k])) for k, v in mine.items())
    assert err <= 1e-8 * R, err
    row = sim.history[-1]
    inclined = sim._symmetry.inclined
    if n_pieces == 3:
        assert inclined == []            # both planes are velocity conditions
        assert "symmetry_violation" not in row
    else:
        assert len(inclined) == (2 if start else 1)
        assert row["symmetry_violation"] <= 1e-12 * V_DIE
    # the planes push on the body along their inward normal -n (compression spreads the body)
    _, ft, normals = sector_mesh(comm, n_pieces, start)
    for name, key in (("plane0", "sym0"), ("plane1", "sym1")):
        f = np.array([row[f"{name}_{c}"] for c in "xyz"])
        n = normals[key]
        assert f @ n < 0, (name, f)
        assert np.linalg.norm(f - (f @ n) * n) <= 1e-8 * np.linalg.norm(f), (name, f)
    # both planes carry the hoop resultant through a meridian half-plane: equal normal forces
    # (a velocity condition and a projection, or two projections, alike)
    f0 = np.array([row[f"plane0_{c}"] for c in "xyz"]) @ normals["sym0"]
    f1 = np.array([row[f"plane1_{c}"] for c in "xyz"]) @ normals["sym1"]
    assert abs(f0 - f1) <= 1e-7 * abs(f0), (f0, f1)


def test_inclined_parallel_matches_serial():
    """The third with two inclined planes: the same answer on COMM_WORLD and COMM_SELF."""
    comm = MPI.COMM_WORLD
    Fw, x0w, x1w, sw = upset_world(4, 30.0)
    Fs, x0s, x1s, ss = upset(MPI.COMM_SELF, 4, 30.0)
    for a, b in zip(Fw, Fs):
        assert abs(a - b) <= 1e-8 * abs(b)
    ref = _gather(MPI.COMM_SELF, x0s, x1s)
    mine = _gather(comm, x0w, x1w)
    assert len(ref) == len(mine)
    assert max(np.max(np.abs(v - ref[k])) for k, v in mine.items()) <= 1e-8 * R
    for rw, rs in zip(sw.history, ss.history):
        for c in "xyz":
            assert abs(rw[f"plane1_{c}"] - rs[f"plane1_{c}"]) <= 1e-8 * abs(rs["die_z"])


def test_bad_plane():
    """Facets that are not on one plane of the given normal are refused on every rank."""
    comm = MPI.COMM_WORLD
    msh, ft, normals = sector_mesh(comm, 4)
    space = MixedSpace(msh)
    planes = SymmetryPlanes(space)
    with pytest.raises(ValueError, match="not on one plane"):
        planes.add("p", ft.indices[ft.values == TAGS["sym1"]], normals["sym0"])
    with pytest.raises(ValueError, match="not on one plane"):
        planes.add("p", ft.indices[ft.values == TAGS["top"]], normals["sym1"])
    with pytest.raises(ValueError, match="non-zero"):
        planes.add("p", ft.indices[ft.values == TAGS["sym1"]], (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="length 3"):
        planes.add("p", ft.indices[ft.values == TAGS["sym1"]], (1.0, 0.0))


def test_projected_jacobian_and_residual():
    """The projected Jacobian is P A P + Q Qᵀ (mat-vec against the raw Jacobian and the
    vertex blocks), the tangent of the projected residual along directions that keep the
    constraints (central finite differences), and the projected residual vanishes in the
    constrained directions once the predictor is projected (two inclined planes, the axis
    included)."""
    import dolfinx.fem.petsc
    from petsc4py import PETSc

    comm = MPI.COMM_WORLD
    msh, ft, normals = sector_mesh(comm, 4, 30.0)
    space = MixedSpace(msh)
    # the consistent tangent: the finite-difference check below is of the exact Jacobian (the
    # primal-dual one depends on the dual stress too, tests/test_dual.py)
    sim = Simulation(space, NortonHoff(K=50.0, m=0.3, regularization=1e-2), progress=False,
                     solver_options=SolverOptions(material_tangent="consistent"))
    fac = lambda name: sim.facets(ft, TAGS[name])  # noqa: E731
    sim.add_velocity_bc(fac("bottom"), 0.0, 2)
    sim.add_velocity_bc(fac("top"), -V_DIE, 2)
    sim.add_symmetry_plane(fac("sym0"), normals["sym0"], name="plane0")
    sim.add_symmetry_plane(fac("sym1"), normals["sym1"], name="plane1")
    sim._build()
    planes, prob, w = sim._symmetry, sim.problem, sim.w
    assert planes.inclined == ["plane0", "plane1"]
    n_axis = comm.allreduce(int(np.sum([np.linalg.matrix_rank(q) == 2 for q in planes._QQ])))
    assert n_axis > 0                                    # vertices on both planes
    rng = np.random.default_rng(comm.rank)
    nown = space.num_owned_dofs
    w.x.array[:nown] = rng.normal(size=nown)
    w.x.scatter_forward()
    dolfinx.fem.petsc.set_bc(w.vector, prob.bcs)
    w.x.scatter_forward()
    planes.project(w)
    assert planes.max_violation(w) < 1e-13
    A = prob.assemble_jacobian()
    # P A P keeps the mixed space's vertex-block pattern: the values are copied (the
    # mat-vec check below is of that path)
    assert planes._same and all(planes._same.values())
    A0 = prob.create_matrix()
    dolfinx.fem.petsc.assemble_matrix(A0, prob.a, bcs=prob.bcs)
    A0.assemble()

    def project(vec, keep_q=False):
        """vec ← P vec, or Q Qᵀ vec with keep_q (owned rows)."""
        arr = vec.getArray()
        d = planes.dofs
        x = arr[d].copy() if len(d) else np.zeros((0, 3))
        qx = np.einsum("nde,ne->nd", planes._QQ, x)
        if keep_q:
            arr[:] = 0.0
            arr[d] = qx
        else:
            arr[d] = x - qx

    x = A.createVecRight()
    x.setArray(rng.normal(size=x.getLocalSize()))
    y, px, t, qx = x.duplicate(), x.duplicate(), x.duplicate(), x.duplicate()
    A.mult(x, y)
    x.copy(px)
    project(px)
    A0.mult(px, t)
    project(t)
    x.copy(qx)
    project(qx, keep_q=True)
    t.axpy(1.0, qx)
    t.axpy(-1.0, y)
    assert t.norm() <= 1e-12 * y.norm()
    # finite differences along a direction that keeps the constraints and the BCs
    d = x.copy()
    project(d)
    d.getArray()[prob.bc_marker[:nown]] = 0.0
    w0 = w.vector.copy()
    eps = 1e-6
    r = []
    for s in (1.0, -1.0):
        w0.copy(w.vector)
        w.vector.axpy(s * eps, d)
        w.x.scatter_forward()
        r.append(prob.assemble_residual().copy())
    fd = (r[0] - r[1]) / (2 * eps)
    w0.copy(w.vector)
    w.x.scatter_forward()
    A = prob.assemble_jacobian(A)
    Ad = d.duplicate()
    A.mult(d, Ad)
    assert (fd - Ad).norm() <= 1e-6 * Ad.norm(), ((fd - Ad).norm(), Ad.norm())
    # constrained rows of the residual hold the (zero) violation
    b = prob.assemble_residual()
    q = b.copy()
    project(q, keep_q=True)
    assert q.norm() <= 1e-12 * b.norm()
    for v in (A0, x, y, px, t, qx, d, w0, Ad, b, q, *r):
        v.destroy()
    assert isinstance(A, PETSc.Mat)
