"""Nodal penalty contact: scheme derivatives (FD), kernel twin, penalty consistency against
boundary conditions, explicit vs implicit on a curved tool, Newton convergence, bad input, MPI."""

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Tresca
from fxcontact.contact.nodal import NodalContact, penalty_from_beta
from fxcontact.contact.penalty import Penalty, penalty_kernel, penalty_kernel_numpy
from fxcontact.kinematics import CartesianUpdate, CylindricalUpdate
from fxcontact.materials import LinearElastic, NortonHoff
from fxcontact.meshing import BILLET_TAGS, BLOCK_TAGS, block, cylinder_billet
from fxcontact.newton.options import SolverOptions
from fxcontact.newton.problem import NodalTerms
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Cone, Cylinder, Plane, Sphere

from helpers import FakeBoundary as _FakeBoundary
from helpers import gather_by_position


# ----------------------------------------------------------------------------- unit level
class _FakeSim:
    def __init__(self, kin, w_prev):
        self.kinematics = kin
        self.material = NortonHoff(1.0, 0.5)
        self.w_prev = type("F", (), {"x": type("X", (), {"array": w_prev})()})()


def _energy(c, v):
    h = c._constraint(v.reshape(-1, 3), False)[0]
    return 0.5 * c.rho * np.sum(c.boundary.areas * np.maximum(h, 0.0) ** 2)


TOOLS = {
    "plane": lambda: Plane((0, 0, 1.0), (0.2, -0.1, -1.0), velocity=(0.1, 0, -0.3)),
    "sphere": lambda: Sphere((0.2, 0.1, 3.0), 2.0, velocity=(0, 0, -0.2)),
    "cylinder": lambda: Cylinder((0, 0, 3.0), (1, 0.2, 0), 2.0, velocity=(0, 0.1, -0.2),
                                 angular_velocity=0.7),
    "bore": lambda: Cylinder((0, 0, -2.0), (0, 1, 0.1), 3.05, inside=True),
    "cone": lambda: Cone((0, 0, 4.0), (0, 0.1, 1.0), 0.6, velocity=(0, 0, -0.5)),
}


@pytest.mark.parametrize("scheme", ["explicit", "quasi-implicit", "implicit", "implicit-exact"])
@pytest.mark.parametrize("tool", list(TOOLS))
@pytest.mark.parametrize("kin", ["cartesian", "cylindrical"])
def test_scheme_residual_and_jacobian_fd(scheme, tool, kin):
    """r = ∇Φ for every scheme (FD); K = ∇r for all but the Gauss–Newton 'implicit'."""
    rng = np.random.default_rng(3)
    n = 12
    t0, dt = 0.3, 0.1
    tl = TOOLS[tool]()
    # points near the tool surface, half of them slightly inside
    y = rng.uniform(-1.0, 1.0, (n, 3)) + np.array([1.5, 0.3, 0.9])
    pr = tl.project(y, t0)
    s = np.linspace(-0.15, 0.15, n)
    x = pr.point + s[:, None] * pr.normal
    v = rng.normal(scale=0.5, size=(n, 3))
    b = _FakeBoundary(n)
    kinematics = CartesianUpdate() if kin == "cartesian" else \
        CylindricalUpdate(center=(0.0, 0.0, 0.0), axis=(0.0, 0.3, 1.0))
    c = NodalContact(b, tl, scheme=scheme, penalty=7.0,
                     max_initial_penetration=10.0)
    sim = _FakeSim(kinematics, (v + 0.2 * rng.normal(size=v.shape)).ravel())
    c.begin_increment(sim, t0, dt, x)
    c.begin_solve()
    # implicit-exact uses the exact tangent once the active set has settled: two unchanged
    # iterates, as in Newton's convergence test
    c.evaluate(v.ravel(), False)
    c.stable()
    assert c.stable()
    terms = c.evaluate(v.ravel(), True)
    assert np.any(c._h > 0) and np.any(c._h <= 0)  # both active and inactive nodes
    r, K = terms.residual, terms.jacobian
    eps = 1e-6
    g_fd = np.zeros_like(v)
    K_fd = np.zeros((n, 3, 3))
    for a in range(3):
        dv = np.zeros_like(v)
        dv[:, a] = eps
        # Φ is a sum of nodal terms: one FD per component for all nodes at once
        for i in range(n):
            e = np.zeros_like(v)
            e[i, a] = eps
            g_fd[i, a] = (_energy(c, v + e) - _energy(c, v - e)) / (2 * eps)
        rp = c.evaluate((v + dv).ravel(), False).residual
        rm = c.evaluate((v - dv).ravel(), False).residual
        K_fd[:, :, a] = (rp - rm) / (2 * eps)
    assert np.linalg.norm(r - g_fd) <= 1e-6 * np.linalg.norm(r)
    if scheme == "implicit":
        # Gauss–Newton: exact up to the curvature term, which is present on curved tools
        return
    # nodes near h = 0 make the FD non-smooth: compare only nodes away from the kink
    c.evaluate(v.ravel(), False)
    far = np.abs(c._h) > 1e-3
    assert np.linalg.norm((K - K_fd)[far]) <= 1e-6 * np.linalg.norm(K[far])


def test_penalty_kernel_twin():
    rng = np.random.default_rng(0)
    n = 50
    S, h = rng.random(n), rng.normal(size=n)
    g = rng.normal(size=(n, 3))
    Hh = rng.normal(size=(n, 3, 3))
    act = (h > 0) | (rng.random(n) > 0.5)
    for H in (Hh, np.zeros((0, 3, 3))):
        r1, K1 = penalty_kernel(S, 3.0, h, g, H, act, True)
        r2, K2 = penalty_kernel_numpy(S, 3.0, h, g, H, act, True)
        assert np.allclose(r1, r2, rtol=1e-14, atol=1e-14)
        assert np.allclose(K1, K2, rtol=1e-14, atol=1e-14)


def test_bad_contact_input():
    b = _FakeBoundary(3)
    tool = Plane((0, 0, 0), (0, 0, 1))
    with pytest.raises(ValueError, match="scheme"):
        NodalContact(b, tool, scheme="semi-implicit", penalty=1.0)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="penalty"):
            NodalContact(b, tool, penalty=bad)
    with pytest.raises(ValueError, match="tools"):
        NodalContact(b, [], penalty=1.0)
    with pytest.raises(ValueError, match="only one"):
        NodalContact(b, tool, penalty=1.0, gap_stiffness=2.0)
    # a node buried deeper than the limit: clear error naming the tool and the depth
    c = NodalContact(b, Plane((0, 0, 0), (0, 0, 1), name="die"), penalty=1.0,
                     max_initial_penetration=0.1)
    x = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -0.5], [1.0, 0.0, 0.05]])
    with pytest.raises(ValueError, match="buried in tool 'die'.*0.5"):
        c.begin_increment(_FakeSim(CartesianUpdate(), np.zeros(9)), 0.0, 0.1, x)


def test_penalty_given_as_one_object():
    """``NodalContact(penalty=Penalty(...))``: the contact resolves its own copy (the object
    given is not changed), with the values given; a Penalty with beta/gap_stiffness/strain_rate
    beside it is refused; the run is that of the same values given as numbers."""
    b, tool = _FakeBoundary(3), Plane((0, 0, 0), (0, 0, 1))
    for kw in (dict(penalty=2.0), dict(beta=50.0, strain_rate=2.0), dict(gap_stiffness=3.0),
               {}):
        p = Penalty(**kw)
        c, ref = NodalContact(b, tool, penalty=p), NodalContact(b, tool, **kw)
        assert c.penalty is not p
        assert c.penalty.signature() == ref.penalty.signature() == p.signature()
        assert c.penalty.strain_rate == ref.penalty.strain_rate
    for kw in (dict(beta=1.0), dict(gap_stiffness=1.0), dict(strain_rate=1.0)):
        with pytest.raises(ValueError, match=f"penalty is a Penalty: give .*{next(iter(kw))}"):
            NodalContact(b, tool, penalty=Penalty(beta=10.0), **kw)
    # ρ and β together: refused, not β dropped in silence
    for make in (lambda: Penalty(penalty=5.0, beta=10.0),
                 lambda: NodalContact(b, tool, penalty=5.0, beta=10.0)):
        with pytest.raises(ValueError, match="only one of penalty .* and beta"):
            make()
    p = Penalty(gap_stiffness=2e6)
    runs = [_strip_under_arc(MPI.COMM_WORLD, "implicit", 0.4, t_end=0.8, penalty=pen)[0]
            for pen in (p, None)]
    assert len(runs[0].history) == 2 and runs[0].history[-1]["contact_nodes"] > 0
    # bitwise on one rank; on several, parallel MUMPS is not bitwise reproducible run to run
    rel = 0.0 if MPI.COMM_WORLD.size == 1 else 1e-9
    for key in ("arc_force_x", "arc_force_y", "contact_penetration_true"):
        a, b = ([q[key] for q in r.history] for r in runs)
        assert a == pytest.approx(b, rel=rel, abs=0.0), key
    assert p.fixed_rho is None and p.stiffness == 2e6           # the object given: unchanged


def test_node_on_tool_axis_is_a_clear_error():
    """A contact node on a roll's axis is deep inside the roll: error, never NaN."""
    from fxcontact.newton.problem import ContributorError
    b = _FakeBoundary(2)
    roll = Cylinder((0, 0, 0), (0, 1, 0), 1.0, name="roll")
    c = NodalContact(b, roll, scheme="implicit", penalty=1.0, max_initial_penetration=10.0)
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 3.0]])
    c.begin_increment(_FakeSim(CartesianUpdate(), np.zeros(6)), 0.0, 0.1, x)
    with pytest.raises(ContributorError, match="axis"):
        c.evaluate(np.zeros(6), True)
    # away from contact a node on an axis is harmless (bore axis in free space)
    bore = Cylinder((0, 0, 0), (0, 1, 0), 5.0, inside=True)
    c2 = NodalContact(b, bore, scheme="implicit", penalty=1.0)
    c2.begin_increment(_FakeSim(CartesianUpdate(), np.zeros(6)), 0.0, 0.1, x)
    t = c2.evaluate(np.zeros(6), True)
    assert np.all(np.isfinite(t.residual)) and np.all(np.isfinite(t.jacobian))


# ----------------------------------------------------------------------------- FE level
def _upsetting(comm, contact, penalty=None, scheme="implicit", n_inc=3, h=4.0):
    R, H, V = 10.0, 15.0, 5.0
    msh, _, ft = cylinder_billet(comm, R, H, h)
    sp = MixedSpace(msh)
    sim = Simulation(sp, NortonHoff(50.0, 0.15, regularization=1e-4), progress=False)
    f = {k: sim.facets(ft, v) for k, v in BILLET_TAGS.items()}
    sim.add_velocity_bc(f["symmetry_x"], 0.0, 0)
    sim.add_velocity_bc(f["symmetry_y"], 0.0, 1)
    sim.add_velocity_bc(f["bottom"], 0.0, 2)
    c = None
    if contact:
        die = Plane((0, 0, H), (0, 0, -1), velocity=(0, 0, -V), name="die")
        c = sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BILLET_TAGS["top"]), die,
                                             scheme=scheme, penalty=penalty))
    else:
        sim.add_velocity_bc(f["top"], -V, 2)
        sim.add_reaction("die", f["top"])
    sim.run(0.2 * n_inc, 0.2)
    return sim, c


def _vertex_velocities(sim):
    sp = sim.space
    own = sp.vertex_owned
    x0 = sim._x_ref[sp.vertex_geometry][own]  # initial positions: a key independent of the run
    return gather_by_position(sim.comm, x0, sim.w.x.array[sp.vertex_dofs[own]])


@pytest.mark.slow
def test_plane_dies_reproduce_sliding_bc_and_penalty_consistency():
    comm = MPI.COMM_WORLD
    ref, _ = _upsetting(comm, False)
    _, vr = _vertex_velocities(ref)
    errs = []
    sims = []
    for pen in (None, "x10"):
        if pen is None:
            s, c = _upsetting(comm, True)
            rho = c.rho
        else:
            s, c = _upsetting(comm, True, penalty=10 * rho)
        x, v = _vertex_velocities(s)
        errs.append(np.max(np.abs(v - vr)) / np.max(np.abs(vr)))
        sims.append((s, c))
    assert errs[0] < 1e-4, errs
    assert 7.0 < errs[0] / errs[1] < 13.0, errs  # ~10x smaller with a 10x penalty
    # the die force equals the reaction of the BC problem, and it acts on the die (+z)
    s, c = sims[1]
    Fz = s.history[-1]["die_force_z"]
    assert Fz > 0
    assert abs(Fz + ref.history[-1]["die_z"]) < 1e-3 * abs(Fz)
    assert s.history[-1]["contact_nodes"] > 0


def _strip_under_arc(comm, scheme, dt, t_end=3.2, R=200.0, k=2e6, penalty=None):
    """A Norton–Hoff strip dragged (bottom velocity 1) under a concave arc: the inside of a
    large bore whose highest point is above the strip's rear end and which passes through the
    strip's top front corner, so the strip is progressively thinned as it advances."""
    msh, _, ft = block(comm, [-8.0, -2.0], [0.0, 0.0], 0.25, dim=2)
    sp = MixedSpace(msh)
    sim = Simulation(sp, NortonHoff(10.0, 0.3, regularization=1e-4), progress=False)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), np.array([1.0, 0.0]))
    arc = Cylinder((-8.0, -np.sqrt(R**2 - 64.0), 0.0), (0, 0, 1), R, inside=True, name="arc")
    sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["ymax"]), arc,
                                     scheme=scheme, **(dict(penalty=penalty) if penalty
                                                        else dict(gap_stiffness=k))))
    sim.run(t_end, dt)
    pen = max(r["contact_penetration_true"] for r in sim.history)
    return sim, pen


@pytest.mark.slow
def test_explicit_error_grows_with_dt_squared_implicit_does_not():
    comm = MPI.COMM_WORLD
    pens = {}
    for scheme in ("explicit", "implicit"):
        for dt in (0.1, 0.4):
            _, pens[(scheme, dt)] = _strip_under_arc(comm, scheme, dt)
    if comm.rank == 0:
        print("\nmax true penetration:", {f"{k[0]} dt={k[1]}": f"{v:.3e}" for k, v in
                                          pens.items()})
    ratio_exp = pens[("explicit", 0.4)] / pens[("explicit", 0.1)]
    ratio_imp = pens[("implicit", 0.4)] / pens[("implicit", 0.1)]
    assert ratio_exp >= 8.0, pens
    assert abs(ratio_imp - 1.0) <= 0.2, pens
    assert pens[("implicit", 0.4)] < 0.2 * pens[("explicit", 0.4)]


def test_implicit_exact_converges_quadratically():
    comm = MPI.COMM_WORLD
    its = {}
    norms = {}
    for scheme in ("implicit", "implicit-exact"):
        msh, _, ft = block(comm, [-4.0, -2.0], [4.0, 0.0], 0.5, dim=2)
        sp = MixedSpace(msh)
        sim = Simulation(sp, NortonHoff(10.0, 0.3, regularization=1e-4), progress=False,
                         solver_options=None)
        sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), np.array([0.0, 0.0]))
        roll = Cylinder((0.0, 3.0 - 0.05, 0.0), (0, 0, 1), 3.0, velocity=(0.0, -0.5, 0.0),
                        name="roll")
        sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["ymax"]), roll,
                                         scheme=scheme, penalty=1e3))
        sim.step(0.1)
        res = sim.step(0.1)
        its[scheme] = res.info.iterations
        norms[scheme] = res.info.residual_norms
    assert its["implicit-exact"] <= its["implicit"], its
    r = np.array(norms["implicit-exact"])
    r = r[r > 1e-11 * r[0]]
    # quadratic: the last reductions accelerate (log ratio of successive contractions ≥ 1.5)
    if len(r) >= 4:
        q = np.log(r[-1] / r[-2]) / np.log(r[-2] / r[-3])
        assert q > 1.5, r


def test_implicit_exact_robust_to_large_predictor_penetration():
    """Stiff elastic block indented by a cylinder with a large penalty: the predictor
    penetrates far more than the converged state, where the curvature term ρS[h]₊∇²h (negative
    tangentially) would exceed the structural stiffness. implicit-exact must not need more
    Newton iterations than the Gauss–Newton implicit scheme in any increment (the exact tangent
    from the first iterate took 8 vs 3 and 7 vs 2 here)."""
    comm = MPI.COMM_WORLD
    for beta in (1e3, 1e4):
        its = {}
        for scheme in ("implicit", "implicit-exact"):
            msh, _, ft = block(comm, [0.0, -2.0], [4.0, 0.0], 0.5,
                               refine_box=((0.0, -0.5), (1.0, 0.0)), h_fine=0.05, dim=2)
            sp = MixedSpace(msh)
            mat = LinearElastic(2e5, 0.3)
            sim = Simulation(sp, mat, progress=False)
            sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["xmin"]), 0.0, 0)
            sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), 0.0, 1)
            tool = Cylinder((0.0, 3.0, 0.0), (0, 0, 1), 3.0, velocity=(0.0, -0.03, 0.0))
            dt = 1.0 / 3.0
            sim.add_contributor(NodalContact(
                ContactBoundary(sp, ft, BLOCK_TAGS["ymax"]), tool, scheme=scheme,
                penalty=penalty_from_beta(mat, beta, 0.05, dt=dt)))
            its[scheme] = [sim.step(dt, max_cutbacks=0).info.iterations for _ in range(3)]
        assert all(e <= i for e, i in zip(its["implicit-exact"], its["implicit"])), (beta, its)


def test_contact_parallel_matches_serial():
    comm = MPI.COMM_WORLD
    out = []
    for c in (comm, MPI.COMM_SELF):
        s, con = _upsetting(c, True, n_inc=2)
        sp = s.space
        own = sp.vertex_owned
        x, v = gather_by_position(c, s._x_ref[sp.vertex_geometry][own],
                                  s.w.x.array[sp.vertex_dofs[own]])
        out.append((x, v, s.history[-1]))
    (x1, v1, h1), (x2, v2, h2) = out
    assert np.allclose(x1, x2, atol=1e-12)
    assert np.max(np.abs(v1 - v2)) <= 1e-8 * np.max(np.abs(v2))
    for k in ("die_force_z", "contact_area", "contact_nodes", "contact_penetration_true"):
        assert abs(h1[k] - h2[k]) <= 1e-8 * max(abs(h2[k]), 1e-30), k


def test_nagata_fallbacks_reported_per_increment():
    """A faceted Nagata tool whose Newton projection is not allowed to iterate falls back to
    the flat facet: the contact diagnostics report the count at the last evaluation and the sum
    over every evaluation of the increment (reset at the next increment), never silently."""
    from fxcontact.tools.faceted import FacetedTool
    from fxcontact.tools import surfaces

    V, T = surfaces.icosphere(2, radius=2.0, center=(0.0, 0.0, 2.5))
    n = 40
    rng = np.random.default_rng(4)
    x = np.c_[rng.uniform(-1.0, 1.0, (n, 2)), rng.uniform(0.0, 0.4, n)]
    b = _FakeBoundary(n)
    diags = {}
    for max_iter in (0, 30):
        tool = FacetedTool(V, T, mode="nagata", max_iter=max_iter, name="ball")
        c = NodalContact(b, tool, scheme="implicit", penalty=5.0, max_initial_penetration=10.0)
        sim = _FakeSim(CartesianUpdate(), np.zeros(3 * n))
        c.begin_increment(sim, 0.0, 0.1, x)
        for _ in range(3):
            c.evaluate(np.zeros(3 * n), False)
        d = c.diagnostics()
        diags[max_iter] = d
        assert d["contact_fallbacks_all"] == 3 * d["contact_fallbacks"]
        assert d["contact_fallbacks"] == tool.last_fallbacks
        c.begin_increment(sim, 0.1, 0.1, x)
        c.evaluate(np.zeros(3 * n), False)
        assert c.diagnostics()["contact_fallbacks_all"] == c.diagnostics()["contact_fallbacks"]
    assert diags[0]["contact_fallbacks"] > 0.5 * n
    assert diags[30]["contact_fallbacks"] == 0


@pytest.mark.parametrize("pattern", [[0, 1], [0, 1, 1]])
def test_cycle_hint_counts_tool_switches_over_the_cycle(pattern):
    """A node that switches between the two tools of one contact (a container and a die that
    meet) in a 2- or 3-cycle of Newton iterates is reported as switching between the tools,
    counted over the whole cycle (the last step of the 3-cycle A, B, B changes nothing: the
    message said "0 node(s) enter and leave contact")."""
    container = Plane((0, 0, 0.05), (0, 0, -1), name="container")
    die = Plane((0.05, 0, 0), (-1, 0, 0), name="die")
    c = NodalContact(_FakeBoundary(1), [container, die], penalty=1.0,
                     max_initial_penetration=10.0)
    c.begin_increment(_FakeSim(CartesianUpdate(), np.zeros(3)), 0.0, 0.1, np.zeros((1, 3)))
    c.begin_solve()
    vs = [np.array([0.6, 0.0, 1.0]), np.array([1.0, 0.0, 0.6])]
    tools = []
    for k in range(2 * len(pattern) + 1):
        c.evaluate(vs[pattern[k % len(pattern)]], False)
        c.stable()
        tools.append(int(c._tool[0]))
    assert np.all(c._h > 0) and len(set(tools)) == 2     # in contact, with both tools in turn
    hint = c.cycle_hint(len(pattern))
    assert "1 node(s) switch between the tools 'container' and 'die'" in hint
    assert "enter and leave" not in hint and "reduce dt" in hint


def test_tiny_dt_converges_at_the_round_off_floor():
    """The README's upsetting with dt = 1e-6: the contact gap of a node at x is known to
    ε|x| only, so the contact forces to ρS ε|x|/dt, above the relative tolerance of the
    residual of an increment that starts from a good predictor; Newton stopped there as a
    "cycle" with "0 node(s) enter and leave contact: reduce dt". It converges at that floor."""
    msh, _, ft = cylinder_billet(MPI.COMM_WORLD, radius=10.0, height=15.0, h=4.0)
    space = MixedSpace(msh)
    sim = Simulation(space, NortonHoff(K=50.0, m=0.15), progress=False)
    for key, comp in (("symmetry_x", 0), ("symmetry_y", 1), ("bottom", 2)):
        sim.add_velocity_bc(sim.facets(ft, BILLET_TAGS[key]), 0.0, component=comp)
    die = Plane(point=(0, 0, 15.0), normal=(0, 0, -1), velocity=(0, 0, -5.0), name="die")
    contact = NodalContact(ContactBoundary(space, ft, BILLET_TAGS["top"]), die)
    sim.add_contributor(contact)
    history = sim.run(t_end=3e-6, dt=1e-6, max_cutbacks=0)
    assert len(history) == 3 and all(r["cutbacks"] == 0 for r in history)
    assert history[-1]["contact_nodes"] > 0 and history[-1]["die_force_z"] > 0


class _GarbageAttempts:
    """Contributor that, in every Newton solve of the increments numbered ``bad`` (0-based) at
    dt > 0.15, pushes the contact nodes with large random forces (N) drawn afresh at each
    evaluation and never reports a settled state: every attempt at that dt wanders off and
    fails, and the cut-back attempt (dt/2) runs clean. Adds nothing elsewhere."""

    def __init__(self, dofs, bad):
        self.dofs, self.bad = dofs, set(bad)
        self.rng = np.random.default_rng(1 + MPI.COMM_WORLD.rank)
        self.on = False
        self.seen = 0      # garbage evaluations

    def begin_increment(self, sim, t, dt, x):
        self.on = len(sim.history) in self.bad and dt > 0.15

    def evaluate(self, w, jacobian):
        n = len(self.dofs)
        if not self.on:
            return NodalTerms.empty(3)
        self.seen += 1
        r = self.rng.normal(scale=1e4, size=(n, 3))
        return NodalTerms(self.dofs, r, np.zeros((n, 3, 3)) if jacobian else None)

    def stable(self):
        return not self.on


def _upsetting_steps(dts, bad=()):
    """The upsetting of _upsetting with Tresca friction on the die, stepped by ``dts`` (at most
    one cut-back), the attempts at dt > 0.15 of the increments ``bad`` failed by garbage."""
    msh, _, ft = cylinder_billet(MPI.COMM_WORLD, 10.0, 15.0, 4.0)
    sp = MixedSpace(msh)
    sim = Simulation(sp, NortonHoff(50.0, 0.15, regularization=1e-4), progress=False,
                     solver_options=SolverOptions(max_it=12))
    for key, comp in (("symmetry_x", 0), ("symmetry_y", 1), ("bottom", 2)):
        sim.add_velocity_bc(sim.facets(ft, BILLET_TAGS[key]), 0.0, component=comp)
    die = Plane((0, 0, 15.0), (0, 0, -1), velocity=(0, 0, -5.0), name="die")
    c = sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BILLET_TAGS["top"]), die,
                                         friction=Tresca(0.3)))
    g = sim.add_contributor(_GarbageAttempts(c.boundary.dofs, bad))
    for dt in dts:
        sim.step(dt, max_cutbacks=1)
    return sim, g


@pytest.mark.serial   # bitwise: parallel MUMPS is not reproducible from run to run
def test_failed_attempts_leave_nothing():
    """An increment accepted after failed attempts and the increments after it are those of a
    run that takes the same steps without failing, bitwise: nothing of the failed attempts
    (their iterates, dual stress, contact and friction states, factorisations, the consistent
    tangent and the line search of the fall-backs) reaches them."""
    sim, g = _upsetting_steps([0.2] * 4, bad={1})
    ref, _ = _upsetting_steps([0.2, 0.1, 0.2, 0.2])
    assert [r["cutbacks"] for r in sim.history] == [0, 1, 0, 0] and g.seen > 0
    # three failed attempts at dt = 0.2 (the primal-dual tangent, the consistent one, the
    # fall-back line search; the last one's factorisation fails), each followed by a reset
    assert sim.solver.resets == 3 and ref.solver.resets == 0
    for a, b in zip(ref.history, sim.history):
        for key in ("time", "dt", "die_force_z", "residual", "newton_iterations",
                    "linear_iterations", "contact_nodes", "volume"):
            assert a[key] == b[key], (key, a["increment"], a[key], b[key])
    assert np.array_equal(ref.w.x.array, sim.w.x.array)
    assert np.array_equal(ref.mesh.geometry.x, sim.mesh.geometry.x)
