"""Idle tools solved inside Newton (fxcontact.idle.IdleRotation, method="bordered"): finite
differences of the border terms ∂R/∂ω, ∂T/∂v, ∂T/∂ω (every friction law, numba = numpy), the
local elimination of ω (zero torque on every idle tool), the Woodbury-corrected linear solve
against a dense solve, and the ring-rolling case: the bordered and the outer methods give the
same ω and forces, 1 and 2 ranks agree."""

import math
from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact.contact.friction import Coulomb, Norton, Tresca
from fxcontact.contact.nodal import NodalContact
from fxcontact.kinematics import CartesianUpdate
from fxcontact.materials import LinearElastic
from fxcontact.idle import ControlledMotion, IdleRotation
from fxcontact.processes import RingRollingCase, ring_rolling
from fxcontact.newton.solver import BorderedPC, BorderedOperator
from fxcontact.tools.analytic import Cylinder, Plane
from fxcontact.tools.base import MovedTool

from helpers import FakeBoundary


class _FakeSim:
    def __init__(self, w):
        self.kinematics = CartesianUpdate()
        self.material = LinearElastic(1.0, 0.3)
        self.w = w
        self.w_prev = type("F", (), {"x": type("X", (), {"array": w})()})()


LAWS = {
    "coulomb": Coulomb(0.3, mbar=0.8, shear_limit=0.9),    # both branches appear
    "tresca": Tresca(0.6, shear_limit=1.5),
    "norton": Norton(0.5, 0.2, K=2.0),
}

T0, DT = 0.3, 0.1

#: two rolls (axis, axis point, radius, ω): nodes near each
ROLLS = [((1.0, 0.2, 0.0), (0.0, 0.0, 3.0), 2.0, 0.9),
         ((0.0, 1.0, 0.3), (0.5, 0.0, -3.0), 1.5, -1.4)]


def _case(law, two=False, backend="numba", seed=5):
    """Nodes near one roll (or two), half of them moving nearly with the roll's surface (the
    steep, sticking part of T(ω)), the others slipping; implicit contact and friction with
    the consistent friction tangent."""
    rng = np.random.default_rng(seed)
    rolls, x, v = [], [], []
    for k, (axis, point, radius, om) in enumerate(ROLLS[: 2 if two else 1]):
        mot = ControlledMotion(velocity=(0.2, -0.1 * k, -0.1), angular_velocity=om,
                               axis_point=point, axis=axis)
        roll = MovedTool(Cylinder(point, axis, radius, name=f"roll{k}"), mot, name=f"roll{k}")
        rolls.append(roll)
        n = 12
        y = np.array(point) + rng.uniform(-1.0, 1.0, (n, 3)) * 2.0
        pr = roll.project(y, T0)
        s = np.linspace(-0.25, 0.08, n)
        xk = pr.point + s[:, None] * pr.normal
        vk = rng.normal(scale=0.5, size=(n, 3))
        stick = np.arange(n) % 2 == 0
        vk[stick] = roll.velocity(pr.point[stick], T0) + rng.normal(scale=0.02,
                                                                    size=(int(stick.sum()), 3))
        x.append(xk)
        v.append(vk)
    x, v = np.vstack(x), np.vstack(v)
    b = FakeBoundary(len(x), seed=seed)
    c = NodalContact(b, rolls, scheme="implicit", penalty=1.0, max_initial_penetration=10.0,
                     friction=law, slip_velocity=0.05, friction_tangent="consistent",
                     backend=backend)
    idle = IdleRotation(c, rolls, method="bordered")
    return c, idle, rolls, x, v


def _start(c, idle, x, v):
    idle.begin_increment(None, T0, DT, None)
    c.begin_increment(_FakeSim(v.ravel()), T0, DT, x)
    c.begin_solve()


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("law", list(LAWS))
def test_border_terms_fd(law, backend):
    """∂R/∂ω, ∂T/∂v and ∂T/∂ω of the border equal central finite differences of the contact's
    residual entries and of the torque about the tool's axis (NodalContact.tool_torque). The
    projection is frozen (quasi-implicit scheme) so that the differences see the friction's
    dependence on v and ω only — what the border holds: the contact's own Jacobian also leaves
    out the dependence of the projection on the iterate (THEORY §9)."""
    c, idle, rolls, x, v = _case(LAWS[law], backend=backend)
    c.scheme = "quasi-implicit"
    mot = rolls[0].motion
    om = mot.current_angular_velocity()
    _start(c, idle, x, v)
    c.evaluate(v.ravel(), True)
    (dofs, u, g, D), = idle.border_terms(v.ravel())
    assert len(dofs) >= 6
    if law == "coulomb":
        assert {1, 2} <= set(c._branch[c._h > 0].tolist())
    sim = _FakeSim(v.ravel())

    def at_omega(w):
        mot.set_rates(T0, angular_velocity=w)
        c.begin_increment(sim, T0, DT, x)      # the tool velocity is frozen per increment
        r = c.evaluate(v.ravel(), False).residual.copy()
        return r, c.tool_torque(0)

    eps = 1e-6
    (rp, Tp), (rm, Tm) = at_omega(om + eps), at_omega(om - eps)
    at_omega(om)
    dR = (rp - rm) / (2 * eps)
    node = dofs[:, 0] // 3
    assert np.linalg.norm(dR[node] - u) <= 1e-6 * np.linalg.norm(u)
    others = np.setdiff1d(np.arange(len(x)), node)
    assert np.max(np.abs(dR[others]), initial=0.0) <= 1e-9 * np.max(np.abs(u))
    assert (Tp - Tm) / (2 * eps) == pytest.approx(D, rel=1e-6)
    assert D < 0          # T decreases with ω
    g_fd = np.zeros_like(g)
    for i, nd in enumerate(node):
        for a in range(3):
            e = np.zeros_like(v)
            e[nd, a] = eps
            c.evaluate((v + e).ravel(), False)
            tp = c.tool_torque(0)
            c.evaluate((v - e).ravel(), False)
            g_fd[i, a] = (tp - c.tool_torque(0)) / (2 * eps)
    assert np.linalg.norm(g_fd - g) <= 1e-6 * np.linalg.norm(g)


def test_border_terms_numba_equals_numpy():
    """The border through the numba friction kernel equals the one through its numpy twin."""
    out = []
    for backend in ("numba", "numpy"):
        c, idle, rolls, x, v = _case(LAWS["coulomb"], two=True, backend=backend)
        _start(c, idle, x, v)
        c.evaluate(v.ravel(), True)
        out.append(idle.border_terms(v.ravel()))
    for a, b in zip(*out):
        assert np.array_equal(a[0], b[0])
        assert np.allclose(a[1], b[1], rtol=1e-13, atol=0)
        assert np.allclose(a[2], b[2], rtol=1e-13, atol=0)
        assert a[3] == pytest.approx(b[3], rel=1e-13)


@pytest.mark.parametrize("law", list(LAWS))
def test_elimination_zeroes_every_torque(law):
    """At an iterate, the elimination sets each idle roll's ω so that its torque (contact +
    friction, NodalContact.tool_torque at the contact's new terms) vanishes to round-off of
    the friction torques; with two rolls the speeds are found together."""
    c, idle, rolls, x, v = _case(LAWS[law], two=True)
    _start(c, idle, x, v)
    c.evaluate(v.ravel(), False)
    T_before = [c.tool_torque(k) for k in range(2)]
    w_before = [r.motion.current_angular_velocity() for r in rolls]
    idle._eliminate(v.ravel(), False)
    for k, roll in enumerate(rolls):
        sel = c._tool == k
        e = np.asarray(roll.motion.axis) / np.linalg.norm(roll.motion.axis)
        arm = c._point[sel] - roll.motion.axis_point_at(T0 + DT)
        scale = float(np.sum(np.linalg.norm(np.cross(e, arm), axis=1)
                             * np.linalg.norm(c._rf[sel], axis=1)))
        assert scale > 0 and abs(T_before[k]) > 1e-3 * scale
        assert abs(c.tool_torque(k)) <= 1e-10 * scale, (k, c.tool_torque(k), scale)
        assert roll.motion.current_angular_velocity() != w_before[k]


@pytest.mark.parametrize("factor", ["petsc", "mumps"])
def test_woodbury_solve_against_dense(factor):
    """The bordered operator's product and the Woodbury-corrected preconditioner (LU of J)
    reproduce J̃ = J − U D⁻¹ G and its inverse (dense numpy), with k = 2 borders; with MUMPS
    the same for three right-hand sides in one solve (``apply_many``; PETSc's own LU has no
    such solve: ``apply_many`` declines)."""
    rng = np.random.default_rng(1)
    n, k = 30, 2
    Jd = rng.normal(size=(n, n)) + n * np.eye(n)
    Ud, Gd = rng.normal(size=(n, k)), rng.normal(size=(k, n))
    Dd = np.diag([-3.0, -0.7])
    comm = MPI.COMM_SELF
    A = PETSc.Mat().createDense((n, n), array=Jd.copy(), comm=comm)
    A.convert("aij")
    A.assemble()

    def vec(a):
        x = PETSc.Vec().createSeq(n, comm=comm)
        x.setArray(a)
        return x
    U, G = [vec(Ud[:, j].copy()) for j in range(k)], [vec(Gd[j].copy()) for j in range(k)]
    border = type("B", (), {"vectors": lambda self: (U, G, Dd)})()
    Jt = Jd - Ud @ np.linalg.solve(Dd, Gd)
    op = BorderedOperator(A, border)
    S = PETSc.Mat().createPython((n, n), op, comm=comm)
    S.setUp()
    x, y = vec(rng.normal(size=n)), vec(np.zeros(n))
    S.mult(x, y)
    assert np.allclose(y.getArray(), Jt @ x.getArray(), rtol=1e-12, atol=1e-12)
    inner = PETSc.PC().create(comm)
    inner.setType("lu")
    inner.setFactorSolverType(factor)
    ksp = PETSc.KSP().create(comm)
    ksp.setType("preonly")
    ksp.setOperators(S, A)
    pc = ksp.getPC()
    pc.setType("python")
    pc.setPythonContext(BorderedPC(inner, border))
    rhs = vec(rng.normal(size=n))
    sol = vec(np.zeros(n))
    ksp.solve(rhs, sol)
    ref = np.linalg.solve(Jt, rhs.getArray())
    assert np.allclose(sol.getArray(), ref, rtol=1e-10, atol=1e-12)
    xs = [vec(rng.normal(size=n)) for _ in range(3)]
    ys = [vec(np.zeros(n)) for _ in range(3)]
    done = pc.getPythonContext().apply_many(xs, ys)
    assert done == (factor == "mumps")
    if done:
        for x_, y_ in zip(xs, ys):
            assert np.allclose(y_.getArray(), np.linalg.solve(Jt, x_.getArray()), rtol=1e-10,
                               atol=1e-12)
    ksp.destroy()
    S.destroy()
    A.destroy()


def test_bad_inputs():
    c, idle, rolls, x, v = _case(LAWS["coulomb"], two=True)
    with pytest.raises(ValueError, match="method"):
        IdleRotation(c, rolls[0], method="newton")
    with pytest.raises(ValueError, match="one tool"):
        IdleRotation(c, rolls, method="outer")
    with pytest.raises(ValueError, match="twice"):
        IdleRotation(c, [rolls[0], rolls[0]])
    # a tool that is not a surface of revolution about its rotation axis
    mot = ControlledMotion(angular_velocity=1.0, axis_point=(0, 0, 0), axis=(0, 0, 1))
    plate = MovedTool(Plane((0, 0, 1.0), (0, 0, -1.0), name="plate"), mot, name="plate")
    off = MovedTool(Cylinder((0.5, 0, 0), (0, 0, 1), 1.0, name="off"),
                    ControlledMotion(angular_velocity=1.0, axis_point=(0, 0, 0)), name="off")
    b = FakeBoundary(3)
    c2 = NodalContact(b, [plate, off], scheme="implicit", penalty=1.0, friction=Tresca(0.5, 1.0))
    for tool in (plate, off):
        with pytest.raises(ValueError, match="revolution"):
            IdleRotation(c2, tool, method="bordered")
        assert IdleRotation(c2, tool).method == "outer"
    c3 = NodalContact(FakeBoundary(3), rolls, scheme="explicit", penalty=1.0)
    with pytest.raises(ValueError, match="implicit"):
        IdleRotation(c3, rolls[0], method="bordered")
    assert IdleRotation(c3, rolls[0]).method == "outer"
    assert IdleRotation(c, rolls[0]).method == "bordered"


# --------------------------------------------------------------------- ring rolling
#: one increment of the quick (coarse) case 2: Coulomb friction on the main roll and the idle
#: mandrel
ONE = RingRollingCase.case2().quick()
ONE = replace(ONE, revolutions=1.0 / ONE.increments_per_rev)


@pytest.fixture(scope="module")
def ring():
    return {m: ring_rolling.run(replace(ONE, idle_method=m)) for m in ("bordered", "outer")}


def test_ring_bordered_equals_outer(ring):
    """The bordered method (one Newton solve, ω eliminated at every evaluation) and the outer
    iteration (several Newton solves on T(ω) = 0) give the same mandrel speed and forces:
    the outer one stops at |T| ≤ 1e-6 |F| R̄, which moves ω by far less than 1e-6 relative;
    the bordered torque is zero to round-off (below 1e-3 of that tolerance)."""
    b, o = ring["bordered"].history, ring["outer"].history
    assert ring["bordered"].status == ring["outer"].status == "done"
    assert len(b) == len(o) == 1
    qb, qo = b[0], o[0]
    assert qb["nodes_mandrel"] > 0 and qb["mandrel_solves"] == 1 and qo["mandrel_solves"] > 1
    assert abs(qb["mandrel_idle_torque"]) <= 1e-3 * qb["mandrel_idle_tolerance"]
    assert abs(qo["mandrel_idle_torque"]) <= qo["mandrel_idle_tolerance"]
    assert qb["mandrel_omega"] == pytest.approx(qo["mandrel_omega"], rel=1e-6)
    # force vectors to 1e-6 of their size; the main roll's torque to 1e-6 of |F| R1
    F = {}
    for tool in ("main", "mandrel"):
        F[tool] = [np.array([q[f"{tool}_force_x"], q[f"{tool}_force_y"]]) for q in (qb, qo)]
        assert np.linalg.norm(F[tool][0] - F[tool][1]) <= 1e-6 * np.linalg.norm(F[tool][1])
    R1 = ring["outer"].case.R1
    assert abs(qb["main_torque"] - qo["main_torque"]) <= 1e-6 * np.linalg.norm(F["main"][1]) * R1
    for key in ("ring_omega", "outer_diameter"):
        assert qb[key] == pytest.approx(qo[key], rel=1e-6), key
    print(f"omega bordered {qb['mandrel_omega']:.12g}, outer {qo['mandrel_omega']:.12g}; "
          f"Newton iterations {qb['newton_iterations']} vs {qo['newton_iterations']}")


def test_ring_bordered_one_and_two_ranks_agree(ring):
    """The bordered increment on all ranks (the module's run) and on COMM_SELF agree to 1e-8."""
    if MPI.COMM_WORLD.size == 1:
        pytest.skip("compares a run on 2 ranks with a serial one (run under mpirun -n 2)")
    res = ring_rolling.run(replace(ONE, idle_method="bordered"), comm=MPI.COMM_SELF)
    a, b = ring["bordered"].history[0], res.history[0]
    for k in ("main_force_x", "main_torque", "mandrel_force_x", "mandrel_omega",
              "ring_omega", "outer_diameter"):
        assert abs(a[k] - b[k]) <= 1e-8 * abs(b[k]), (k, a[k], b[k])
    assert math.isfinite(a["mandrel_idle_torque"])


def test_ring_three_idle_tools(monkeypatch):
    """Mandrel and both guide rolls idle with Coulomb friction, in one IdleRotation (three
    borders), the guide rolls pressed on the ring: one Newton solve, every torque zero to
    round-off, and each idle roll turns at the body's rolling speed (surface slip of the order
    of the slip regularisation v₀ = 1e-3 of the roll speed, not a free-wheeling mismatch)."""
    from fxcontact import idle as mill
    from fxcontact.processes.ring_rolling import process as ring_process
    made = []

    class Captured(mill.IdleRotation):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            made.append(self)
    monkeypatch.setattr(ring_process, "IdleRotation", Captured)
    res = ring_rolling.run(replace(ONE, idle_guides=True, guide_clearance=-0.2))
    assert res.status == "done"
    idle, = made
    assert idle.method == "bordered" and [t.name for t in idle.tools] == \
        ["mandrel", "guide1", "guide2"]
    q = res.history[0]
    assert q["nodes_guides"] > 0 and q["nodes_mandrel"] > 0
    d = idle.diagnostics()
    v0 = 1e-3 * 2 * math.pi * 150.0
    for name in ("mandrel", "guide1", "guide2"):
        assert d[f"{name}_idle_solves"] == 1
        assert abs(d[f"{name}_idle_torque"]) <= 1e-3 * d[f"{name}_idle_tolerance"], name
        assert abs(d[f"{name}_surface_slip"]) < 5 * v0, (name, d[f"{name}_surface_slip"])
    # the guide rolls turn against the ring's outer surface (clockwise about +z)
    assert d["guide1_omega"] < 0 and d["guide2_omega"] < 0
