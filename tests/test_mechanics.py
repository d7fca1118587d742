"""Foundation: Norton–Hoff compression, elastic patch test, MPI agreement, bad input."""

import re

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx

from fxcontact.materials import LinearElastic, NortonHoff
from fxcontact.simulation import Simulation
from fxcontact.newton.solver import SolverOptions
from fxcontact.spaces import MixedSpace, facets_with_tags

from helpers import assert_newton_counts_match, box_mesh, gather_by_position


def _faces(msh, L):
    fdim = msh.topology.dim - 1
    loc = dolfinx.mesh.locate_entities_boundary
    return {
        "x0": loc(msh, fdim, lambda x: np.isclose(x[0], 0.0)),
        "y0": loc(msh, fdim, lambda x: np.isclose(x[1], 0.0)),
        "z0": loc(msh, fdim, lambda x: np.isclose(x[2], 0.0)),
        "z1": loc(msh, fdim, lambda x: np.isclose(x[2], L[2])),
    }


def compression(comm, m, a=0.02, dt=0.1, n_inc=10, K=10.0, n=(3, 3, 3), perturb=0.15,
                solver_options=None, volume_correction="global"):
    """Cube compressed between sliding plates: a fraction ``a`` of the height per increment."""
    L = (1.0, 1.0, 1.0)
    msh = box_mesh(comm, L, n, perturb=perturb)
    space = MixedSpace(msh)
    sim = Simulation(space, NortonHoff(K=K, m=m, regularization=1e-8), progress=False,
                     solver_options=solver_options, volume_correction=volume_correction)
    f = _faces(msh, L)
    H0 = L[2]

    def top(t):
        k = int(round(t / dt)) - 1  # increments already done
        return -a * H0 * (1 - a) ** k / dt

    sim.add_velocity_bc(f["x0"], 0.0, 0)
    sim.add_velocity_bc(f["y0"], 0.0, 1)
    sim.add_velocity_bc(f["z0"], 0.0, 2)
    sim.add_velocity_bc(f["z1"], top, 2)
    sim.add_reaction("top", f["z1"])
    out = []
    V0 = sim.volume()
    for i in range(n_inc):
        area = sim.volume() / (H0 * (1 - a) ** i)  # uniform deformation: A = V/H
        sim.step(dt)
        F = sim.history[-1]["top_z"]
        out.append(dict(stress=F / area, div=sim.history[-1]["div_v"], volume=sim.volume(),
                        V=sim.volume(), restore=sim.history[-1]["volume_restore_rate"]))
    return sim, out, V0


@pytest.mark.parametrize("m,correction", [(0.3, "global"), (0.14, "global"), (0.3, "none")])
def test_uniaxial_compression_norton_hoff(m, correction):
    """Homogeneous compression (exact for P1): flow stress, discrete incompressibility and the
    volume after each increment from the update of a homogeneous flow: with the plain
    ``div v = 0`` each increment multiplies the volume by ``(1 + a/2)²(1 − a)`` (the error of
    the first-order update accumulates); with the volume correction the lateral stretch rate
    also gives back ``ln(V/V⁰)/dt``: ``V ← V (1 + (a − ln(V/V⁰))/2)² (1 − a)``."""
    a, dt, K = 0.02, 0.1, 10.0
    sim, out, V0 = compression(MPI.COMM_WORLD, m, a=a, dt=dt, K=K, volume_correction=correction)
    rate = a / dt
    sigma = -np.sqrt(3.0) * K * (np.sqrt(3.0) * rate) ** m
    vol = V0
    for i, o in enumerate(out):
        # axial stress = -sqrt(3) K (sqrt(3) rate)^m within 0.5 %
        assert abs(o["stress"] / sigma - 1.0) < 5e-3, (i, o["stress"], sigma)
        # discrete incompressibility: |∫div v - restore rate| < 1e-8 V rate
        c = np.log(vol / V0) if correction == "global" else 0.0
        assert abs(o["restore"] + vol * c / dt) <= 1e-10 * vol * rate, (i, o["restore"], c)
        assert abs(o["div"] - o["restore"]) < 1e-8 * vol * rate, (i, o["div"], o["restore"])
        vol *= (1 + (a - c) / 2) ** 2 * (1 - a)
        assert abs(o["volume"] / vol - 1.0) < 1e-6, (i, o["volume"], vol)
    drift = out[-1]["volume"] / V0 - 1.0
    if correction == "global":  # one increment's second-order error, not ten
        assert abs(drift) < 2.0 * abs((1 + a / 2) ** 2 * (1 - a) - 1.0), drift
    else:
        assert abs(drift) > 5.0 * abs((1 + a / 2) ** 2 * (1 - a) - 1.0), drift
    assert len(sim.history) == 10
    assert all(r["newton_iterations"] >= 1 for r in sim.history)


def test_compression_parallel_matches_serial():
    """The distributed run equals a serial run of the same problem (on COMM_SELF) to 1e-8."""
    comm = MPI.COMM_WORLD
    sims = {}
    for name, c in (("world", comm), ("self", MPI.COMM_SELF)):
        sim, out, _ = compression(c, 0.2, n_inc=3, perturb=0.1)
        sims[name] = (sim, out)
    res = {}
    for name, (sim, out) in sims.items():
        sp = sim.space
        owned = sp.vertex_owned
        x = sp.vertex_positions()[owned]
        v = sim.w.x.array[sp.vertex_dofs[owned]]
        res[name] = gather_by_position(sim.comm if name == "world" else comm, x, v) \
            if name == "world" else gather_by_position(MPI.COMM_SELF, x, v)
    xw, vw = res["world"]
    xs, vs = res["self"]
    assert xw.shape == xs.shape
    assert np.allclose(xw, xs, atol=1e-12)
    assert np.max(np.abs(vw - vs)) <= 1e-8 * np.max(np.abs(vs))
    for o_w, o_s in zip(sims["world"][1], sims["self"][1]):
        for k in ("stress", "volume"):
            assert abs(o_w[k] - o_s[k]) <= 1e-8 * abs(o_s[k])
    for rw, rs in zip(sims["world"][0].history, sims["self"][0].history):
        assert abs(rw["volume"] - rs["volume"]) <= 1e-8 * rs["volume"]
        assert_newton_counts_match(rw["newton_iterations"], rs["newton_iterations"])


def test_fieldsplit_matches_mumps_and_options_do_not_leak():
    """The Schur field split (preset, or a dict with pc_type=fieldsplit) gives the MUMPS
    solution (Krylov rtol 1e-10 -> velocities within 1e-7), and a later MUMPS solver under the
    same prefix does not inherit the field-split options."""
    from fxcontact.newton.solver import LINEAR_SOLVERS
    from petsc4py import PETSc

    comm = MPI.COMM_WORLD
    ref, out_ref, _ = compression(comm, 0.2, n_inc=2)
    custom = dict(LINEAR_SOLVERS["fieldsplit"], pc_fieldsplit_schur_fact_type="full")
    for lin in ("fieldsplit", custom):
        sim, out, _ = compression(comm, 0.2, n_inc=2,
                                  solver_options=SolverOptions(linear_solver=lin))
        assert sim.solver.snes.getKSP().getPC().getType() == "fieldsplit"
        assert sim.solver.snes.getLinearSolveIterations() > 0
        dv = np.max(np.abs(sim.w.x.array - ref.w.x.array))
        assert dv <= 1e-7 * np.max(np.abs(ref.w.x.array)), dv
        for o, r in zip(out, out_ref):
            assert abs(o["stress"] / r["stress"] - 1.0) < 1e-7
    after, _, _ = compression(comm, 0.2, n_inc=1)
    assert after.solver.snes.getKSP().getPC().getType() == "lu"
    keys = PETSc.Options().getAll()
    assert not any(k.startswith("fxc_pc_fieldsplit") or k.startswith("fxc_fieldsplit")
                   for k in keys), sorted(keys)


def test_elastic_patch_test():
    """Uniform uniaxial stress on a distorted mesh is reproduced exactly (1e-10)."""
    comm = MPI.COMM_WORLD
    L = (1.0, 2.0, 1.5)
    msh = box_mesh(comm, L, (3, 4, 3), perturb=0.25, seed=3)
    E, nu, s0, dt = 200.0, 0.3, -1.7, 0.5
    mat = LinearElastic(E, nu)
    space = MixedSpace(msh)
    fdim = 2
    ftop = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[2], L[2]))
    tags = dolfinx.mesh.meshtags(msh, fdim, np.sort(ftop), np.full(len(ftop), 7, np.int32))
    ds = ufl.ds(domain=msh, subdomain_data=tags)
    traction = dolfinx.fem.Constant(msh, np.array([0.0, 0.0, s0]))

    def extra(v, p, w, q):
        return -ufl.inner(traction, w) * ds(7)

    sim = Simulation(space, mat, extra_residual=extra, progress=False)
    f = _faces(msh, L)
    sim.add_velocity_bc(f["x0"], 0.0, 0)
    sim.add_velocity_bc(f["y0"], 0.0, 1)
    sim.add_velocity_bc(f["z0"], 0.0, 2)
    sim.step(dt)
    x = space.vertex_positions()  # reference mesh (small strain)
    u_exact = np.c_[-nu * s0 / E * x[:, 0], -nu * s0 / E * x[:, 1], s0 / E * x[:, 2]]
    v = sim.w.x.array[space.vertex_dofs]
    err = np.max(np.abs(dt * v - u_exact))
    err = comm.allreduce(err, op=MPI.MAX)
    assert err <= 1e-10 * np.max(np.abs(u_exact)) + 1e-14, err
    p = sim.w.x.array[space.Q_to_W]
    assert np.allclose(p, -s0 / 3.0, rtol=1e-10, atol=1e-12)
    # the displacement is accumulated: a second increment with the same load does nothing
    sim.step(dt)
    v2 = sim.w.x.array[space.vertex_dofs]
    assert np.max(np.abs(v2)) <= 1e-10 * np.max(np.abs(v))


@pytest.mark.parametrize("kwargs", [dict(K=0.0, m=0.2), dict(K=-1.0, m=0.2),
                                    dict(K=1.0, m=0.0), dict(K=1.0, m=1.5),
                                    dict(K=float("nan"), m=0.2), dict(K=1.0, m=0.2,
                                                                      regularization=0.0)])
def test_bad_norton_hoff(kwargs):
    with pytest.raises(ValueError):
        NortonHoff(**kwargs)


@pytest.mark.parametrize("E,nu", [(0.0, 0.3), (-5.0, 0.3), (1.0, 0.5), (1.0, -1.0),
                                  (1.0, 0.7)])
def test_bad_elastic(E, nu):
    with pytest.raises(ValueError, match="E|nu"):
        LinearElastic(E, nu)


def test_bad_dt_and_missing_tag():
    comm = MPI.COMM_WORLD
    msh = box_mesh(comm, n=(2, 2, 2))
    space = MixedSpace(msh)
    sim = Simulation(space, NortonHoff(1.0, 0.2), progress=False)
    for dt in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="dt"):
            sim.step(dt)
    fdim = 2
    f = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[2], 0.0))
    tags = dolfinx.mesh.meshtags(msh, fdim, np.sort(f), np.full(len(f), 1, np.int32))
    with pytest.raises(ValueError, match="tag 5"):
        facets_with_tags(msh, tags, 5)
    with pytest.raises(ValueError, match="element"):
        MixedSpace(msh, element="P3")
    with pytest.raises(ValueError, match="quadrature"):
        MixedSpace(msh, quadrature_degree=3)


def test_material_derivatives_fd():
    """Norton–Hoff: s = ∂φ/∂ε and D = ∂s/∂ε by central finite differences (numpy reference)."""
    rng = np.random.default_rng(0)
    mat = NortonHoff(K=3.0, m=0.14, regularization=1e-2)
    for _ in range(5):
        a = rng.normal(size=(3, 3))
        eps = 0.5 * (a + a.T)
        h = 1e-6
        g = np.zeros((3, 3))
        for i in range(3):
            for j in range(3):
                d = np.zeros((3, 3))
                d[i, j] = h
                g[i, j] = (mat.potential(eps + d) - mat.potential(eps - d)) / (2 * h)
        s = mat.stress(eps)
        gs = 0.5 * (g + g.T)  # gradient w.r.t. a symmetric tensor
        assert np.linalg.norm(gs - s) < 1e-6 * np.linalg.norm(s)
        D = mat.tangent(eps)
        Dfd = np.zeros((3, 3, 3, 3))
        for k in range(3):
            for l in range(3):
                d = np.zeros((3, 3))
                d[k, l] += 0.5 * h
                d[l, k] += 0.5 * h
                Dfd[:, :, k, l] = (mat.stress(eps + d) - mat.stress(eps - d)) / (2 * h)
        assert np.linalg.norm(Dfd - D) < 1e-6 * np.linalg.norm(D)


class _UnsettledAboveDt:
    """Contributor that adds nothing but never reports a settled state when dt > limit: Newton
    then runs out of iterations, like a contact that cannot settle with a too large step."""

    def __init__(self, limit):
        self.limit, self.dt = limit, 0.0

    def begin_increment(self, sim, t, dt, x):
        self.dt = dt

    def evaluate(self, w, jacobian):
        from fxcontact.newton.problem import NodalTerms
        return NodalTerms.empty(3)

    def stable(self):
        return self.dt <= self.limit


def _pressed_cube(max_it, contributor, fallback=None, material_tangent="consistent"):
    """A Norton–Hoff unit cube pressed on its top face, Newton capped at ``max_it``
    iterations, with ``contributor`` deciding when a state is settled (no fallback line
    search unless asked, and the consistent tangent, so without the primal–dual tangent's
    retry: every failed attempt is then a cut-back)."""
    comm = MPI.COMM_WORLD
    L = (1.0, 1.0, 1.0)
    msh = box_mesh(comm, L, (2, 2, 2))
    sim = Simulation(MixedSpace(msh), NortonHoff(K=10.0, m=0.3), progress=False,
                     solver_options=SolverOptions(max_it=max_it, line_search_fallback=fallback,
                                                  material_tangent=material_tangent))
    f = _faces(msh, L)
    for key, comp in (("x0", 0), ("y0", 1), ("z0", 2)):
        sim.add_velocity_bc(f[key], 0.0, comp)
    sim.add_velocity_bc(f["z1"], -0.1, 2)
    sim.add_contributor(contributor)
    return sim


def test_cutback_halves_dt_and_counts_failed_iterations():
    from fxcontact.simulation import IncrementError

    sim = _pressed_cube(4, _UnsettledAboveDt(0.03))
    res = sim.step(0.1, max_cutbacks=3)          # 0.1, 0.05 fail; 0.025 passes
    row = res.row
    assert row["cutbacks"] == 2 and abs(row["dt"] - 0.025) < 1e-15 and abs(sim.t - 0.025) < 1e-15
    assert row["newton_iterations_all"] == row["newton_iterations"] + 2 * 4
    assert row["wall_increment_all"] >= row["wall_increment"]
    with pytest.raises(IncrementError, match="t = 0.025"):
        sim.step(0.2, max_cutbacks=1)            # 0.2, 0.1 both fail
    assert len(sim.history) == 1 and abs(sim.t - 0.025) < 1e-15


class _UnsettledFirstAttempt(_UnsettledAboveDt):
    """Never settles during the first Newton solve, settles from the second one on."""

    def __init__(self):
        super().__init__(0.0)
        self.solves = 0

    def begin_solve(self):
        self.solves += 1

    def stable(self):
        return self.solves > 1


@pytest.mark.parametrize("fallback", [None, "basic"])
def test_fallback_line_search_before_cutback(fallback):
    """A failed attempt is retried at the same dt with the fallback line search (when one is
    set) before dt is cut back; the failed iterations are counted either way."""
    sim = _pressed_cube(4, _UnsettledFirstAttempt(), fallback=fallback)
    row = sim.step(0.1, max_cutbacks=2).row
    assert row["cutbacks"] == (1 if fallback is None else 0)
    assert abs(row["dt"] - (0.05 if fallback is None else 0.1)) < 1e-15
    assert row["newton_iterations_all"] == row["newton_iterations"] + 4


def test_primal_dual_failure_is_retried_with_the_consistent_tangent():
    """A failed attempt with the primal–dual tangent is retried at the same dt with the
    consistent one (before the line-search fallback and the cut-back); the dual stress is back
    on for the next increment, and the failed iterations are counted."""
    sim = _pressed_cube(4, _UnsettledFirstAttempt(), material_tangent="primal-dual")
    row = sim.step(0.1, max_cutbacks=2).row
    assert row["cutbacks"] == 0 and abs(row["dt"] - 0.1) < 1e-15
    assert row["newton_iterations_all"] == row["newton_iterations"] + 4
    assert sim.dual is not None and sim.dual.active
    updates = sim.dual.updates
    sim.step(0.1)
    assert sim.dual.updates > updates


class _ShrinkingLimit(_UnsettledAboveDt):
    """Settles only for dt ≤ dt0 / 2^(n + 1) after n accepted increments: every increment
    succeeds after cut-backs, with ever smaller steps whose sum never reaches t_end."""

    def __init__(self, dt0):
        super().__init__(dt0)
        self.dt0 = dt0

    def begin_increment(self, sim, t, dt, x):
        self.dt = dt
        self.limit = self.dt0 * 0.5 ** (len(sim.history) + 1)


def test_run_stops_when_dt_would_creep_below_the_floor():
    """Sub-increments that keep needing cut-backs end in an IncrementError once dt would fall
    below dt / 2**max_cutbacks, instead of creeping on forever (the steps here sum to less than
    0.1, so t_end = 1 would never be reached)."""
    from fxcontact.simulation import IncrementError

    sim = _pressed_cube(3, _ShrinkingLimit(0.1))
    with pytest.raises(IncrementError, match="smallest allowed 0.0125"):
        sim.run(1.0, 0.1, max_cutbacks=3)
    # accepted: 0.05, 0.025, 0.0125; the fourth increment would need 0.00625 < 0.1 / 2³
    assert [round(r["dt"], 12) for r in sim.history] == [0.05, 0.025, 0.0125]
    assert abs(sim.t - 0.0875) < 1e-12


class _State:
    """Contributor stand-in whose fingerprint is set by the test."""

    def __init__(self):
        self.fp = ()

    def fingerprint(self):
        return self.fp


def _cycle_detector():
    from types import SimpleNamespace

    from fxcontact.newton.solver import ContactNewtonSolver

    fake = SimpleNamespace(_states=[], CYCLE_PERIODS=ContactNewtonSolver.CYCLE_PERIODS,
                           CYCLE_RTOL=ContactNewtonSolver.CYCLE_RTOL)
    return lambda c, f: ContactNewtonSolver._cycle_period(fake, [c], f)


@pytest.mark.parametrize("period", [2, 3, 4])
def test_cycle_detection_periodic_orbit(period):
    """A periodic sequence of (contact state, residual) is reported once it has gone round
    twice after its first period, i.e. at iteration 3p − 1 (0-based)."""
    detect, c = _cycle_detector(), _State()
    found = []
    for k in range(20):
        c.fp = ((k % period,),)
        found.append(detect(c, 10.0 + (k % period)))
    first = found.index(period)
    assert first == 3 * period - 1 and not any(found[:first])


def test_cycle_detection_ignores_converging_and_changing_sequences():
    detect, c = _cycle_detector(), _State()
    # alternating states but a decreasing residual: converging, not a cycle
    for k in range(30):
        c.fp = ((k % 2,),)
        assert detect(c, 1e3 * 0.5 ** k) == 0
    # a settled state with a decreasing residual
    detect, c = _cycle_detector(), _State()
    for k in range(30):
        c.fp = ((7,),)
        assert detect(c, 1e3 * 0.1 ** k) == 0
    # the same residual but states that never repeat
    detect, c = _cycle_detector(), _State()
    for k in range(30):
        c.fp = ((k,),)
        assert detect(c, 5.0) == 0
    # period 2 with a residual that drifts by more than the match tolerance
    detect, c = _cycle_detector(), _State()
    for k in range(30):
        c.fp = ((k % 2,),)
        assert detect(c, (1.0 + 1e-4 * k) * (3.0 if k % 2 else 4.0)) == 0


class _LinearSolverFailsOnce:
    """Contributor that makes the first attempt's linear solve fail, then adds nothing.

    ``mode="nan"``: NaN Jacobian blocks at every vertex (the factorisation fails, and a kept
    factor makes every later solve raise a MUMPS error); ``mode="mumps_memory"``: MUMPS gets
    1 MB of working memory (ICNTL(23)) for the first attempt only (error -9 or -19; a kept
    failed factor is never refactorised, so every retry fails at iteration 0);
    ``mode="nan_residual"``: a NaN residual in the first attempt."""

    KEY = "fxc_mat_mumps_icntl_23"

    def __init__(self, mode):
        self.mode, self.attempts = mode, 0

    def begin_increment(self, sim, t, dt, x):
        from petsc4py import PETSc
        self.attempts += 1
        self.sim = sim
        if self.mode == "mumps_memory":
            if self.attempts == 1:
                PETSc.Options()[self.KEY] = 1
            else:
                PETSc.Options().delValue(self.KEY)

    def evaluate(self, w, jacobian):
        from fxcontact.newton.problem import NodalTerms
        if self.mode in ("nan", "nan_residual") and self.attempts == 1:
            sp = self.sim.space
            dofs = sp.vertex_dofs[np.all(sp.vertex_dofs < sp.num_owned_dofs, axis=1)]
            if self.mode == "nan" and jacobian:
                return NodalTerms(dofs.astype(np.int32), np.zeros(dofs.shape),
                                  np.full((len(dofs), 3, 3), np.nan))
            if self.mode == "nan_residual":
                return NodalTerms(dofs.astype(np.int32), np.full(dofs.shape, np.nan),
                                  np.zeros((len(dofs), 3, 3)) if jacobian else None)
        return NodalTerms.empty(3)

    def stable(self):
        return True


@pytest.mark.parametrize("mode", ["nan", "mumps_memory", "nan_residual"])
def test_cutback_after_linear_solver_failure_succeeds(mode, caplog):
    """After a linear-solver failure (DIVERGED_LINEAR_SOLVE) the cut-back attempt starts from a
    fresh factorisation and converges, to the same velocity as a run that never failed."""
    from petsc4py import PETSc

    c = _LinearSolverFailsOnce(mode)
    try:
        sim = _pressed_cube(10, c)
        res = sim.step(0.1, max_cutbacks=2)
    finally:
        PETSc.Options().delValue(_LinearSolverFailsOnce.KEY)
    assert res.row["cutbacks"] == 1 and c.attempts == 2
    assert sim.solver.resets == 1
    # the cut-back warning gives the true reason
    why = {"nan": r"the linear solve failed at Newton iteration 0 \(Krylov solver: DIVERGED_",
           "mumps_memory": r"the linear solve failed at Newton iteration 0",
           "nan_residual": r"the residual is NaN/inf at Newton iteration 0"}[mode]
    assert any(re.search(why, r.getMessage()) for r in caplog.records
               if r.levelname == "WARNING"), [r.getMessage() for r in caplog.records]
    ref = _pressed_cube(10, _UnsettledAboveDt(1.0))
    ref.step(0.05)
    assert_newton_counts_match(res.row["newton_iterations"], ref.history[-1]["newton_iterations"],
                               bitwise=MPI.COMM_WORLD.size == 1)
    assert np.allclose(sim.w.x.array, ref.w.x.array, rtol=0, atol=1e-10)


def test_iteration_cap_is_named_as_the_reason(caplog):
    """An attempt that ends on the Newton iteration cap is reported as such in the cut-back
    warning and in the IncrementError, with every attempt at the same dt (primal-dual tangent,
    consistent tangent, fallback line search), never as another SNES reason."""
    from fxcontact.simulation import IncrementError

    sim = _pressed_cube(1, _UnsettledAboveDt(10.0), fallback="basic", material_tangent="auto")
    f = _faces(sim.mesh, (1.0, 1.0, 1.0))
    for comp in (0, 1):      # a sticking die: a barrelling, non-uniform flow (nonlinear)
        sim.add_velocity_bc(f["z1"], 0.0, comp)
    with pytest.raises(IncrementError, match=r"Newton iteration cap \(max_it=1\) reached, "
                                             r"residual .* \[SNES DIVERGED_MAX_IT\]"):
        sim.step(0.1, max_cutbacks=1)
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert warnings and all("Newton iteration cap (max_it=1) reached" in w for w in warnings)
    assert not any("LINEAR_SOLVE" in w for w in warnings)


def test_trust_region_retest_of_the_same_iterate_is_not_a_cycle():
    """PETSc's trust region calls the convergence test again, with the same iteration number
    and residual, after each rejected step. Those repeats are not new iterates: they must not
    be taken for a cycle (they were: a 2-cycle with 0 nodes changing, which stopped the trust
    region at the thesis-size wire drawing), nor be added to the residual history; a true
    cycle over iterations is still found."""
    from types import SimpleNamespace

    from petsc4py import PETSc

    from fxcontact.newton.solver import ContactNewtonSolver, SolverOptions

    def solver():
        c = _State()
        c.stable = lambda: True
        fake = SimpleNamespace(problem=SimpleNamespace(contributors=[c]),
                               options=SolverOptions(max_it=100), _rtol=1e-12, _states=[],
                               _norms=[], _f0=None, _last_it=-1, _last_stable=False,
                               _cycle_message="", _ftol_warned=False, _predicted=[], _pivots=[],
                               CYCLE_PERIODS=ContactNewtonSolver.CYCLE_PERIODS,
                               CYCLE_RTOL=ContactNewtonSolver.CYCLE_RTOL,
                               ROUNDOFF_MARGIN=ContactNewtonSolver.ROUNDOFF_MARGIN)
        fake._cycle_period = lambda cs, f: ContactNewtonSolver._cycle_period(fake, cs, f)
        fake._describe_cycle = lambda cs, p, f: ContactNewtonSolver._describe_cycle(
            fake, cs, p, f)
        fake._residual_floor = ContactNewtonSolver._residual_floor
        return fake, c, (lambda it, f: ContactNewtonSolver._converged(fake, None, it,
                                                                      (1.0, 1.0, f)))

    R = PETSc.SNES.ConvergedReason
    fake, c, conv = solver()
    assert conv(0, 100.0) == R.ITERATING
    for it in (1, 2):
        for _ in range(10):              # the first test of the iterate, then 9 rejected steps
            assert conv(it, 100.0 / (it + 1)) == R.ITERATING
    assert fake._norms == [100.0, 50.0, 100.0 / 3]
    # a genuine 2-cycle of iterates (state and residual alternate): stopped at iteration 5
    fake, c, conv = solver()
    reasons = []
    for it in range(8):
        c.fp = ((it % 2,),)
        reasons.append(conv(it, 10.0 + it % 2))
    assert reasons.index(R.DIVERGED_DTOL) == 5
    assert "cycle with period 2" in fake._cycle_message
    # the same state and residual at every iterate: a residual that stagnates, not a cycle of
    # the contact state (the message said "0 node(s) enter and leave contact")
    fake, c, conv = solver()
    c.fp = ((1,),)
    reasons = [conv(it, 10.0) for it in range(8)]
    assert R.DIVERGED_DTOL in reasons
    assert "Newton stagnates: the residual stays at 1.000e+01" in fake._cycle_message
    assert "enter and leave" not in fake._cycle_message
    # ... at the initial residual: not round-off (the message blamed the tolerance), and
    # the active-set prediction named when it corrected each of the steps
    assert "far above the round-off" in fake._cycle_message
    assert "tolerance" not in fake._cycle_message
    assert "active_set_prediction" not in fake._cycle_message
    fake, c, conv = solver()
    c.fp = ((1,),)
    fake._predicted = [True] * 8
    reasons = [conv(it, 10.0) for it in range(8)]
    assert "active_set_prediction=False" in fake._cycle_message
    # a residual that stagnates at 1e-10 of the initial one: the tolerance is blamed
    fake, c, conv = solver()
    c.fp = ((1,),)
    reasons = [conv(it, 10.0 if it == 0 else 1e-9) for it in range(8)]
    assert R.DIVERGED_DTOL in reasons
    assert "the tolerance is below the accuracy" in fake._cycle_message


def test_trust_region_from_rest_starts_with_the_full_newton_step():
    """A trust-region solve from x = 0 (an elastic cube loaded by a body force only, fixed at
    its base: a linear problem, so the full Newton step is the solution) converges in one
    iteration: PETSc's radius would be δ₀‖x‖ = 0, i.e. an absolute 0.2, and the steps would be
    cut to it (TRUST_RADIUS_FROM_REST). A radius set by the user (``snes_tr_delta0``) is kept:
    with 0.2 the same solve takes many iterations, to the same solution."""
    from petsc4py import PETSc
    comm = MPI.COMM_WORLD
    L = (1.0, 1.0, 1.0)
    out = {}
    for delta0 in (None, 0.2):
        msh = box_mesh(comm, L, (2, 2, 2))
        g = dolfinx.fem.Constant(msh, np.array([0.0, 0.0, -50.0]))
        opts = {} if delta0 is None else {"snes_tr_delta0": delta0}
        sim = Simulation(MixedSpace(msh), LinearElastic(E=1000.0, nu=0.3), progress=False,
                         extra_residual=lambda v, p, w, q: -ufl.inner(g, w) * ufl.dx,
                         solver_options=SolverOptions(line_search="trust-region", max_it=60,
                                                      line_search_fallback=None,
                                                      petsc_options=opts))
        f = _faces(msh, L)
        for comp in range(3):
            sim.add_velocity_bc(f["z0"], 0.0, comp)
        res = sim.step(1.0, max_cutbacks=0)
        vz = comm.allreduce(float(np.min(sim.w.x.array)), op=MPI.MIN)
        out[delta0] = (res.row["newton_iterations"], vz)
        if delta0 is None:   # the from-rest radius is not left in the options database
            assert not PETSc.Options().hasName("fxc_snes_tr_delta0")
        sim.solver.destroy()
    assert out[None][0] == 1
    assert out[0.2][0] > 3
    assert out[0.2][1] == pytest.approx(out[None][1], rel=1e-8)
