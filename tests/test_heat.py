"""Heat in the workpiece (fxcontact.heat, THEORY §16): exact and analytic checks of the lumped
backward-Euler scheme, its energy balance on 1 and 2 ranks, the moving mesh, bad inputs.

Units: N, mm, s, °C. The analytic cases use k = 1 N/(s K), ρc = 2 N/(mm² K) (diffusivity
a = 0.5 mm²/s): only the dimensionless groups matter.
"""

import warnings

import numpy as np
import pytest
from mpi4py import MPI
from scipy.optimize import brentq
from scipy.special import erf, erfc, j0, j1

import dolfinx

from fxcontact.heat import SIGMA_SB, AirExchange, HeatProblem, ThermalMaterial
from fxcontact.meshing import BILLET_TAGS, cylinder_billet

from helpers import box_mesh, gather_by_position

COMM = MPI.COMM_WORLD
STEEL = ThermalMaterial(rho_c=3.9, conductivity=30.0)
SLOW = ThermalMaterial(rho_c=2.0, conductivity=1.0)     # a = 0.5 mm²/s


def _bar(comm, length, nx):
    """A bar [0, length] × [0, w]² (w = length/nx: cubes of side w, 6 tetrahedra each), its
    face x = 0 tagged 1 and x = length tagged 2."""
    w = length / nx
    msh = dolfinx.mesh.create_box(comm, [[0.0, 0.0, 0.0], [length, w, w]], [nx, 1, 1],
                                  dolfinx.mesh.CellType.tetrahedron)
    return msh, _tag_faces(msh, {1: (0, 0.0), 2: (0, length)})


def _tag_faces(msh, where):
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    idx, val = [], []
    for tag, (axis, value) in where.items():
        f = dolfinx.mesh.locate_entities_boundary(
            msh, fdim, lambda x, a=axis, v=value: np.isclose(x[a], v))
        idx.append(f)
        val.append(np.full(len(f), tag, dtype=np.int32))
    idx, val = np.concatenate(idx), np.concatenate(val)
    order = np.argsort(idx)
    return dolfinx.mesh.meshtags(msh, fdim, idx[order].astype(np.int32), val[order])


def _max_error(hp, exact, scale):
    return COMM.allreduce(float(np.max(np.abs(hp.T.x.array[:hp.n_owned] - exact)
                                       / scale, initial=0.0)), op=MPI.MAX)


# ---------------------------------------------------------------------------- exact checks
def test_uniform_source_insulated():
    """Insulated body, uniform q: every node rises by q dt/ρc per step (1e-10 relative)."""
    hp = HeatProblem(box_mesh(COMM, L=(2.0, 1.0, 1.0), n=(6, 3, 3), perturb=0.2), STEEL, 20.0)
    q, dt = 2.0, 0.1
    rise = q * dt / STEEL.rho_c
    volume = 2.0
    for n in range(1, 4):
        out = hp.step(dt, source=q)
        T = hp.T.x.array
        assert np.max(np.abs(T - 20.0 - n * rise)) <= 1e-10 * n * rise
        assert out["stored"] == pytest.approx(q * volume * dt, rel=1e-12)
        assert out["generated"] == pytest.approx(q * volume * dt, rel=1e-14)
        assert abs(out["residual"]) <= 1e-10 * out["generated"]
    assert hp.energy() == pytest.approx(3 * q * volume * dt, rel=1e-12)
    assert hp.mean_temperature() == pytest.approx(20.0 + 3 * rise, rel=1e-12)
    hp.close()


def test_source_forms_agree():
    """A number, a DG0 Function and per-cell arrays (owned and ghost, or owned only) give the
    same step."""
    msh = box_mesh(COMM, L=(1.0, 1.0, 1.0), n=(3, 3, 3), perturb=0.1)
    tdim = msh.topology.dim
    imap = msh.topology.index_map(tdim)
    q = dolfinx.fem.Function(dolfinx.fem.FunctionSpace(msh, ("DG", 0)))
    q.x.array[:] = 3.0
    results = []
    for source in (3.0, q, np.full(imap.size_local + imap.num_ghosts, 3.0),
                   np.full(imap.size_local, 3.0)):
        hp = HeatProblem(msh, STEEL, 20.0)
        results.append(hp.step(0.1, source=source)["generated"])
        assert np.max(np.abs(hp.T.x.array - 20.0 - 0.3 / 3.9)) < 1e-10
    assert results == pytest.approx([0.3] * 4, rel=1e-12)


def test_triangles_direct_and_fallback():
    """On triangles too; the direct solver and the MUMPS fallback of a CG that fails (one
    iteration allowed through the ``heat_`` options) give the CG answer."""
    from petsc4py import PETSc

    msh = dolfinx.mesh.create_unit_square(COMM, 8, 8)
    air = AirExchange(0.05, 100.0, emissivity=0.5)
    runs = {}
    for name in ("cg", "direct", "fallback"):
        opts = PETSc.Options()
        if name == "fallback":
            opts["heat_ksp_max_it"] = 1
        try:
            hp = HeatProblem(msh, STEEL, 20.0, air=air, solver="direct" if name == "direct"
                             else "cg")
        finally:
            if name == "fallback":
                del opts["heat_ksp_max_it"]
        out = hp.step(0.1, source=1.0)
        assert abs(out["residual"]) <= 1e-10 * out["stored"]
        assert out["solver"] == ("cg" if name == "cg" else "direct")
        assert out["fallback"] == (name == "fallback")
        runs[name] = hp.T.x.array.copy()
        hp.close()
    for name in ("direct", "fallback"):
        assert np.max(np.abs(runs[name] - runs["cg"])) < 1e-9


def test_remesh_handoff():
    """A new problem on a new mesh takes the old temperature by
    ``fxcontact.remesh.transfer.interpolate_from(old.T, new.T)``: a linear field exactly."""
    from fxcontact.remesh.transfer import interpolate_from

    old = HeatProblem(box_mesh(COMM, n=(3, 3, 3)), STEEL, lambda x: 20.0 + 100 * x[0] + 50 * x[2])
    new = HeatProblem(box_mesh(COMM, n=(4, 5, 3), perturb=0.2), STEEL, 0.0)
    interpolate_from(old.T, new.T)
    X = new.dof_coordinates()
    assert np.max(np.abs(new.T.x.array - (20.0 + 100 * X[:, 0] + 50 * X[:, 2]))) < 1e-10
    T0, C, n = new.T.x.array.copy(), new.capacity(), new.n_owned
    out = new.step(0.01)      # insulated, no source: the heat is conserved
    # to CG's tolerance (rtol 1e-10) of the heat the step moves between the nodes (46 N mm;
    # measured 5e-14 to 1.7e-12 of it, the partition's order of sums deciding)
    moved = COMM.allreduce(float(np.sum(np.abs(C[:n] * (new.T.x.array[:n] - T0[:n])))),
                           op=MPI.SUM)
    assert moved > 1.0 and abs(out["stored"]) <= new.rtol * moved


def test_material_helpers():
    assert STEEL.effusivity == pytest.approx(np.sqrt(3.9 * 30.0))
    assert STEEL.diffusivity == pytest.approx(30.0 / 3.9)
    assert STEEL.heat_share(STEEL) == pytest.approx(0.5)
    assert STEEL.heat_share(0.0) == 1.0
    air = AirExchange(0.01, 20.0, emissivity=0.8)
    TK, TaK = 1000.0 + 273.15, 293.15
    hr = air.radiation_coefficient(np.array([1000.0]))[0]
    assert hr * (TK - TaK) == pytest.approx(0.8 * SIGMA_SB * (TK ** 4 - TaK ** 4), rel=1e-14)
    assert SIGMA_SB == pytest.approx(5.670e-11, rel=1e-3)   # 5.670e-8 W/(m² K⁴) in N/(mm s K⁴)
    varying = ThermalMaterial(lambda T: 3.9 + 0 * T, lambda T: np.full_like(T, 30.0))
    assert varying.temperature_dependent
    assert varying.effusivity_at(np.array([20.0, 500.0])) == pytest.approx(STEEL.effusivity)
    with pytest.raises(ValueError, match="effusivity_at"):
        _ = varying.effusivity


def test_temperature_dependent_constants_match():
    """Callables returning constants give the constant material's answer (same steps)."""
    msh, tags = _bar(COMM, 10.0, 20)
    mats = [SLOW, ThermalMaterial(lambda T: np.full_like(T, 2.0), lambda T: 1.0 + 0 * T)]
    T = []
    for mat in mats:
        hp = HeatProblem(msh, mat, 20.0, facet_tags=tags, fixed={1: 100.0})
        for _ in range(3):
            hp.step(1.0)
        T.append(hp.T.x.array.copy())
    assert np.max(np.abs(T[0] - T[1])) < 1e-9


# ---------------------------------------------------------------------------- analytic checks
def test_semi_infinite_fixed_surface():
    """Semi-infinite body, surface suddenly at T_s: T = T_s + (T_i − T_s) erf(x / 2√(at)).

    Bar of 60 mm, 120 cells in x (0.5 mm), 1 × 1 across; a = 0.5 mm²/s, dt = 0.5 s; compared at
    every vertex at t = 12.5, 25, 37.5, 50 s (4√(at) ≤ 20 mm ≪ 60 mm). Measured max errors 0.57,
    0.28, 0.19, 0.14 % of T_i − T_s (backward Euler: they halve with dt); asserted 1 %.
    """
    msh, tags = _bar(COMM, 60.0, 120)
    Ti, Ts, dt = 20.0, 100.0, 0.5
    hp = HeatProblem(msh, SLOW, Ti, facet_tags=tags, fixed={1: Ts})
    x = hp.dof_coordinates()[:hp.n_owned, 0]
    a = SLOW.diffusivity
    for n in range(1, 101):
        out = hp.step(dt)
        assert abs(out["residual"]) <= 1e-8 * abs(out["fixed"])
        if n % 25 == 0:
            t = n * dt
            exact = Ts + (Ti - Ts) * erf(x / (2 * np.sqrt(a * t)))
            assert _max_error(hp, exact, Ts - Ti) < 0.01, t
    assert hp.energy() > 0


def test_semi_infinite_film_coefficient():
    """Semi-infinite body, film coefficient h to T_∞ on its surface:
    (T − T_i)/(T_∞ − T_i) = erfc ξ − exp(hx/k + h²at/k²) erfc(ξ + h√(at)/k), ξ = x/2√(at).

    The mesh, dt and times of the fixed-surface case; h = 0.2 N/(mm s K) (h√(at)/k = 0.5 to 1).
    Measured max errors 0.29, 0.16, 0.12, 0.10 % of T_∞ − T_i; asserted 1 %.
    """
    msh, tags = _bar(COMM, 60.0, 120)
    Ti, Tinf, h, dt = 20.0, 100.0, 0.2, 0.5
    hp = HeatProblem(msh, SLOW, Ti, facet_tags=tags, air={1: AirExchange(h, Tinf)})
    x = hp.dof_coordinates()[:hp.n_owned, 0]
    a, k = SLOW.diffusivity, SLOW.conductivity
    for n in range(1, 101):
        out = hp.step(dt)
        assert abs(out["residual"]) <= 1e-8 * abs(out["air"])
        if n % 25 == 0:
            t = n * dt
            xi = x / (2 * np.sqrt(a * t))
            theta = erfc(xi) - np.exp(h * x / k + h * h * a * t / k ** 2) * erfc(
                xi + h * np.sqrt(a * t) / k)
            assert _max_error(hp, Ti + (Tinf - Ti) * theta, Tinf - Ti) < 0.01, t


def _bessel_roots(Bi, n):
    """The first n roots of λ J1(λ) = Bi J0(λ): one in each (j_{0,i-1}, j_{0,i}) bracket where
    J0 changes sign (j_{0,0} := 0)."""
    def f(lam):
        return lam * j1(lam) - Bi * j0(lam)

    zeros = [1e-12] + [brentq(j0, (i - 0.25) * np.pi - 0.5, (i - 0.25) * np.pi + 0.5)
                       for i in range(1, n + 1)]
    return np.array([brentq(f, zeros[i] + 1e-12, zeros[i + 1] - 1e-12) for i in range(n)])


def test_cylinder_cooling_bessel():
    """Long cylinder (R = 10 mm, ends insulated) cooling by h to T_∞, Bi = hR/k = 1:
    θ/θ_i = Σ_j 2 Bi / ((λ_j² + Bi²) J0(λ_j)) J0(λ_j r/R) exp(−λ_j² a t/R²).

    Quarter billet of height 2 mm, gmsh size 1 mm (956 tetrahedra), a = 0.5 mm²/s, dt = 1 s
    (ΔFo = 0.005); compared on the axis (r = 0) and on the surface (r = R) at Fo = a t/R² = 0.1,
    0.2, 0.3. Measured max errors 0.31/0.31, 0.07/0.15, 0.13/0.10 % of θ_i (axis/surface);
    asserted 1 %.
    """
    R, Bi = 10.0, 1.0
    k, a = SLOW.conductivity, SLOW.diffusivity
    lam = _bessel_roots(Bi, 30)
    coef = 2 * Bi / ((lam ** 2 + Bi ** 2) * j0(lam))
    msh, _, ft = cylinder_billet(COMM, R, 2.0, 1.0, quarter=True)
    Ti, Tinf = 100.0, 20.0
    hp = HeatProblem(msh, SLOW, Ti, facet_tags=ft,
                     air={BILLET_TAGS["lateral"]: AirExchange(Bi * k / R, Tinf)})
    X = hp.dof_coordinates()[:hp.n_owned]
    r = np.hypot(X[:, 0], X[:, 1])
    where = (r < 1e-9) | (r > R - 1e-6)
    assert COMM.allreduce(int(np.count_nonzero(r < 1e-9)), op=MPI.SUM) >= 2
    dt = 1.0
    for n in range(1, 61):
        out = hp.step(dt)
        assert abs(out["residual"]) <= 1e-8 * abs(out["air"])
        if n % 20 == 0:
            Fo = a * n * dt / R ** 2
            theta = (j0(np.outer(r[where] / R, lam)) * coef * np.exp(-lam ** 2 * Fo)).sum(axis=1)
            err = np.abs((hp.T.x.array[:hp.n_owned][where] - Tinf) / (Ti - Tinf) - theta)
            assert COMM.allreduce(float(np.max(err, initial=0.0)), op=MPI.MAX) < 0.01, Fo


# ---------------------------------------------------------------------------- lumping
def _face_dofs(hp, axis, value):
    X = hp.dof_coordinates()
    return np.flatnonzero(np.isclose(X[:, axis], value)).astype(np.int32)


def test_no_undershoot_after_sudden_hot_contact():
    """A body at 20 °C touched at x = 0 by a tool at 1000 °C (h_c = 100 N/(mm s K)), dt =
    1e-3 s far below ρc h²/(6k) = 5.4e-3 s (h = 0.5 mm): with the lumped capacity every
    temperature stays in [20, 1000] at every step; the consistent capacity (private switch)
    dips below 20 °C ahead of the front."""
    msh, _ = _bar(COMM, 4.0, 8)
    lows = {}
    for consistent in (False, True):
        hp = HeatProblem(msh, STEEL, 20.0)
        hp._consistent_mass = consistent
        face = _face_dofs(hp, 0, 0.0)
        low, high = np.inf, -np.inf
        for _ in range(10):
            out = hp.step(1e-3, contact=(face, 100.0, 1000.0))
            low, high = min(low, hp.min_temperature()), max(high, hp.max_temperature())
            assert out["tools"][0] > 0
            assert abs(out["residual"]) <= 1e-8 * out["tools"][0]
        lows[consistent] = low
        assert high < 1000.0
    assert lows[False] >= 20.0 - 1e-8       # (the solver's tolerance)
    assert lows[True] < 20.0 - 1e-3


# ---------------------------------------------------------------------------- energy, parallel
def _balance_run(comm):
    """Source, air with radiation on the whole boundary, two tools and nodal heat, 5 steps."""
    msh = box_mesh(comm, L=(2.0, 1.0, 1.0), n=(6, 4, 4), perturb=0.15)
    hp = HeatProblem(msh, STEEL, lambda x: 600.0 + 100.0 * x[0],
                     air=AirExchange(0.02, 20.0, emissivity=0.8))
    X = hp.dof_coordinates()
    die = _face_dofs(hp, 0, 0.0)                                 # owned and ghost dofs
    punch = np.flatnonzero(np.isclose(X[:, 0], 2.0) & (X[:, 2] > 0.4)).astype(np.int32)
    top = _face_dofs(hp, 2, 1.0)
    tdim = msh.topology.dim
    ncells = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    mid = dolfinx.mesh.compute_midpoints(msh, tdim, np.arange(ncells, dtype=np.int32))
    q = 5.0 * (1.0 + mid[:, 0] * mid[:, 1])
    balances = []
    for _ in range(5):
        out = hp.step(0.05, source=q, nodal_heat=(top, 2.0 + X[top, 0]),
                      contact={"die": (die, 10.0, 200.0),
                               "punch": (punch, 5.0 + X[punch, 1], 100.0 + X[punch, 2])})
        balances.append(out)
    x, T = gather_by_position(comm, X[:hp.n_owned], hp.T.x.array[:hp.n_owned])
    hp.close()
    return balances, x, T


def test_energy_balance_and_ranks():
    """Each step: |stored − Σ flows| ≤ 1e-8 × the largest term; the balance is the same on every
    rank; the temperatures by vertex position and the balances equal a COMM_SELF run's to
    1e-8."""
    par, x, T = _balance_run(COMM)
    ser, xs, Ts = _balance_run(MPI.COMM_SELF)
    for out, ref in zip(par, ser):
        terms = [out[k] for k in ("stored", "generated", "nodal", "air", "radiation")]
        terms += list(out["tools"].values())
        assert all(abs(t) > 0 for t in terms)
        assert abs(out["residual"]) <= 1e-8 * max(abs(t) for t in terms)
        assert out["air"] < 0 and out["radiation"] < 0 and out["tools"]["die"] < 0
        assert COMM.allgather(out["stored"]) == [out["stored"]] * COMM.size
        for k in ("stored", "generated", "nodal", "air", "radiation"):
            assert out[k] == pytest.approx(ref[k], rel=1e-8, abs=1e-8 * abs(out["stored"]))
        for k in ("die", "punch"):
            assert out["tools"][k] == pytest.approx(ref["tools"][k], rel=1e-8)
    assert np.allclose(x, xs)
    assert np.max(np.abs(T - Ts)) <= 1e-8 * np.max(np.abs(Ts))


def test_contact_areas_given_and_ghosts():
    """Areas given with the contact replace S_n; a contact entry replaces the air at its
    vertices: the same h_c as the air's with the air's ambient gives the air-only answer."""
    msh, _ = _bar(COMM, 4.0, 8)
    air = AirExchange(0.5, 300.0)
    ref = HeatProblem(msh, STEEL, 20.0, air=air)
    out_ref = ref.step(0.01)
    hp = HeatProblem(msh, STEEL, 20.0, air=air)
    face = _face_dofs(hp, 0, 0.0)
    S = hp.areas()
    out = hp.step(0.01, contact=[(face, 0.5, 300.0, S[face])])
    assert np.max(np.abs(hp.T.x.array - ref.T.x.array)) < 1e-10
    assert out["air"] + out["tools"][0] == pytest.approx(out_ref["air"], rel=1e-10)
    total = COMM.allreduce(float(S[:hp.n_owned].sum()), op=MPI.SUM)
    w = 4.0 / 8
    assert total == pytest.approx(2 * w * w + 4 * 4.0 * w, rel=1e-12)


# ---------------------------------------------------------------------------- moving mesh
def test_moving_mesh_capacity_and_areas_follow():
    """After mesh.geometry.x *= 2 the lumped capacity is 8× and the areas 4×: a uniform source
    stores 8× the heat per step for the same temperature rise q dt/ρc."""
    msh = box_mesh(COMM, L=(1.0, 1.0, 1.0), n=(3, 3, 3), perturb=0.1)
    hp = HeatProblem(msh, STEEL, 20.0)

    def total(a):
        return COMM.allreduce(float(a[:hp.n_owned].sum()), op=MPI.SUM)

    C0, S0 = total(hp.capacity()), total(hp.areas())
    assert C0 == pytest.approx(3.9, rel=1e-12) and S0 == pytest.approx(6.0, rel=1e-12)
    out0 = hp.step(0.1, source=1.0)
    msh.geometry.x[:] *= 2.0
    assert total(hp.capacity()) == pytest.approx(8 * C0, rel=1e-12)
    assert total(hp.areas()) == pytest.approx(4 * S0, rel=1e-12)
    T0 = hp.T.x.array.copy()
    out1 = hp.step(0.1, source=1.0)
    assert out1["stored"] == pytest.approx(8 * out0["stored"], rel=1e-10)
    assert np.max(np.abs(hp.T.x.array - T0 - 0.1 / 3.9)) < 1e-10


# ---------------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize("args, match", [
    ((3.9e6, 30.0), r"N/\(mm² K\) = MJ/\(m³ K\): steel ≈ 3.9"),
    ((float("nan"), 30.0), "finite and > 0"),
    ((-3.9, 30.0), "finite and > 0"),
    ((0.0, 30.0), "finite and > 0"),
    ((3.9, 3.0e4), r"N/\(s K\) = W/\(m K\)"),
    ((3.9, 30.0, 1.5), r"\[0, 1\]"),
])
def test_bad_material(args, match):
    with pytest.raises(ValueError, match=match):
        ThermalMaterial(*args)


@pytest.mark.parametrize("args, match", [((50.0, 30.0), "ρc is in"), ((3.9, 0.001), "k is in")])
def test_material_units_warning(args, match):
    with pytest.warns(UserWarning, match=match):
        ThermalMaterial(*args)


def test_bad_air():
    with pytest.warns(UserWarning, match=r"W/\(m² K\)"):
        AirExchange(10.0, 20.0)
    with pytest.raises(ValueError, match=r"emissivity must be in \[0, 1\]"):
        AirExchange(0.01, 20.0, emissivity=1.2)
    with pytest.raises(ValueError, match="≥ 0"):
        AirExchange(-0.01, 20.0)
    with pytest.raises(ValueError, match="absolute zero"):
        AirExchange(0.01, -300.0)


def test_bad_problem_and_step_inputs():
    msh, tags = _bar(COMM, 4.0, 8)
    with pytest.warns(UserWarning, match="kelvin"):
        HeatProblem(msh, STEEL, 2293.15)
    with pytest.raises(ValueError, match="absolute zero"):
        HeatProblem(msh, STEEL, -300.0)
    with pytest.raises(ValueError, match="facet_tags"):
        HeatProblem(msh, STEEL, 20.0, air={1: AirExchange(0.01, 20.0)})
    with pytest.raises(ValueError, match="solver"):
        HeatProblem(msh, STEEL, 20.0, solver="gmres")
    hp = HeatProblem(msh, STEEL, 20.0, facet_tags=tags, air={1: AirExchange(0.01, 20.0)})
    for dt in (float("nan"), -1.0, 0.0):
        with pytest.raises(ValueError, match="dt must be finite and > 0"):
            hp.step(dt)
    face = _face_dofs(hp, 0, 0.0)
    far = _face_dofs(hp, 0, 4.0)      # on the boundary, not on the exchange boundary (tag 1)
    with pytest.raises(ValueError, match=r"\d+ of the \d+ listed vertices .* not on the "
                                         r"exchange boundary"):
        hp.step(0.01, contact=(np.concatenate([face, far]), 10.0, 200.0))
    with pytest.raises(ValueError, match="one value per vertex"):
        hp.step(0.01, contact=(face, np.ones(len(face) + 1), 200.0))
    with pytest.raises(ValueError, match="T_tool must be finite"):
        hp.step(0.01, contact=(face, 10.0, float("nan")))
    with pytest.raises(ValueError, match="absolute zero"):
        hp.step(0.01, contact=(face, 10.0, -500.0))
    with pytest.raises(ValueError, match="outside"):
        hp.step(0.01, nodal_heat=(np.array([hp.n_local], dtype=np.int32), 1.0))
    with pytest.raises(ValueError, match="one value per local cell"):
        hp.step(0.01, source=np.ones(3))
    with pytest.raises(ValueError, match="source must be finite"):
        hp.step(0.01, source=float("nan"))
    with pytest.raises(ValueError, match="must be a tuple"):
        hp.step(0.01, contact=[face, 10.0, 200.0])
    with pytest.warns(UserWarning, match="kelvin"):
        hp.step(0.01, contact=(face, 10.0, 2500.0))
    assert hp.steps == 1          # the refused steps changed nothing
    bad = ThermalMaterial(lambda T: np.where(T > 100.0, np.nan, 3.9), 30.0)
    hot = HeatProblem(msh, bad, lambda x: 50.0 + 100.0 * (x[0] > 2.0))
    with pytest.raises(ValueError, match=r"rho_c\(T\) must be finite"):
        hot.step(0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hp.step(0.01, contact=(face, 10.0, 200.0))    # a good step warns of nothing
