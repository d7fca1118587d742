"""``SolverOptions.reuse_factorisation``: the Newton step by FGMRES on the exact Newton matrix,
preconditioned by a kept factorisation. The same converged increments as a factorisation at
every Newton iteration, with fewer factorisations (counted by PETSc's log events)."""

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

import fxcontact as fx
from fxcontact.solver import SolverOptions
from helpers import vertex_velocities_by_position
from test_condense import pressed_block

#: PETSc log events of a numeric factorisation (LU and L D Lᵀ)
FACTOR_EVENTS = ("MatLUFactorNum", "MatCholFctrNum")


def numeric_factorisations() -> int:
    PETSc.Log.begin()
    return sum(PETSc.Log.Event(e).getPerfInfo()["count"] for e in FACTOR_EVENTS)


def drawing_like(reuse, solver="condensed-mumps", prefix="trf_", **options):
    """Two increments of a nearly rigid-plastic block (Norton–Hoff m = 0.1) pressed by a rigid
    plane with Tresca friction, on two inclined symmetry planes; returns the vertex velocities,
    the Newton iterations per increment and the numeric factorisations of the run (the
    start-up solve's included)."""
    sim = pressed_block(fx.NortonHoff(K=1.0, m=0.1, regularization=1e-3), n=4, solver=solver,
                        prefix=f"{prefix}{reuse}_", friction=fx.Tresca(mbar=0.5))
    sim.solver_options.reuse_factorisation = reuse
    for k, v in options.items():
        setattr(sim.solver_options, k, v)
    f0 = numeric_factorisations()
    sim.run(0.2, 0.1)
    assert sim.solver.options.reuses_factorisation == reuse
    return (vertex_velocities_by_position(sim), [r["newton_iterations"] for r in sim.history],
            numeric_factorisations() - f0)


@pytest.fixture(scope="module")
def without_reuse():
    return drawing_like(False)


@pytest.mark.parametrize("options", [
    {},
    # every step with a kept factorisation fails its Krylov solve: solved again at once
    {"reuse_max_krylov": 1},
    # no line-search pre-check: the failed Krylov step is taken as it is
    {"reuse_max_krylov": 1, "line_search": "trust-region"},
], ids=["default", "krylov-fails", "trust-region"])
def test_same_increments_fewer_factorisations(without_reuse, options):
    ref, its_ref, fact_ref = without_reuse
    if options.get("line_search") == "trust-region":
        ref, its_ref, fact_ref = drawing_like(False, prefix="trf_tr_", **options)
    v, its, fact = drawing_like(True, prefix=f"trf_{len(options)}_", **options)
    # the same converged increments (to the Newton tolerance), the same Newton iterations
    assert np.linalg.norm(v - ref) <= 1e-7 * np.linalg.norm(ref)
    assert len(its) == len(its_ref) == 2
    for a, b in zip(its, its_ref):
        assert abs(a - b) <= 1
    # one factorisation per Newton iteration without the reuse
    assert fact_ref >= sum(its_ref)
    if not options:   # (with 1 Krylov iteration allowed, few kept factorisations can serve)
        assert fact < fact_ref


def test_auto_is_on_with_condensed_mumps_only():
    assert not SolverOptions(linear_solver="condensed-mumps").reuses_factorisation  # default
    assert SolverOptions(linear_solver="condensed-mumps",
                         reuse_factorisation="auto").reuses_factorisation
    for solver in ("mumps", "condensed-amg", "auto"):
        assert not SolverOptions(linear_solver=solver,
                                 reuse_factorisation="auto").reuses_factorisation
    with pytest.raises(ValueError, match="reuse_factorisation=True needs the condensed direct"):
        SolverOptions(linear_solver="mumps", reuse_factorisation=True)
    # the chosen-by-"auto" iterative solver never reuses (nothing to keep)
    opts = SolverOptions(reuse_factorisation=True)
    opts.linear_solver = "condensed-amg"
    assert not opts.reuses_factorisation
    lin = SolverOptions(linear_solver="condensed-mumps",
                        reuse_factorisation=True).linear_options()
    assert lin["ksp_type"] == "fgmres" and lin["condensed_pc_type"] == "lu"
    # an option of the user's wins over the reuse's Krylov settings
    lin = SolverOptions(linear_solver="condensed-mumps", reuse_factorisation=True,
                        petsc_options={"ksp_rtol": 1e-10}).linear_options()
    assert lin["ksp_rtol"] == 1e-10


def test_bordered_with_reuse_refused_on_several_ranks():
    """A bordered Newton system with the kept factorisation hung on 2 ranks (a ring-rolling run
    with an idle mandrel: one rank in an FGMRES solve, the other past the end of the run, every
    time on a loaded machine): refused on more than one rank, on every rank, until understood;
    allowed on one rank (the next test)."""
    sim = pressed_block(fx.NortonHoff(K=1.0, m=0.1, regularization=1e-3), n=2,
                        solver="condensed-mumps", prefix="trf_border_")
    sim.solver_options.reuse_factorisation = True
    sim.run(0.1, 0.1, close=False)

    class Border:
        def vectors(self):
            return None

    if MPI.COMM_WORLD.size > 1:
        with pytest.raises(ValueError, match="reuse_factorisation is not supported with a "
                                             "bordered Newton system.*on more than one rank"):
            sim.solver.set_border(Border())
    else:
        sim.solver.set_border(Border())
        assert sim.solver.border is not None
    sim.close()


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="refused on several ranks (the test above)")
def test_ring_idle_tool_bordered_with_reuse(monkeypatch):
    """One ring-rolling increment with the idle mandrel eliminated by the bordered Newton
    matrix (friction on both rolls): with the kept factorisation (the Woodbury border built
    on it) the same converged forces and speeds as with a factorisation per iteration."""
    from dataclasses import replace

    from fxcontact.processes import RingRollingCase, ring_rolling
    one = RingRollingCase.case2(idle_method="bordered").quick()
    one = replace(one, revolutions=2.0 / one.increments_per_rev)
    res = {}
    for flag in (True, False):
        def options(*a, _flag=flag, **k):
            return SolverOptions(*a, linear_solver="condensed-mumps", reuse_factorisation=_flag,
                                 prefix=f"trf_ring_{_flag}_", **k)
        monkeypatch.setattr(fx, "SolverOptions", options)
        f0 = numeric_factorisations()
        run = ring_rolling.run(one)
        assert run.status == "done"
        res[flag] = run.history, numeric_factorisations() - f0
    (a, fa), (b, fb) = res[True], res[False]
    assert len(a) == len(b) == 2
    for ra, rb in zip(a, b):
        for k in ("main_force_x", "main_torque", "mandrel_force_x", "mandrel_omega",
                  "ring_omega"):
            assert abs(ra[k] - rb[k]) <= 1e-6 * abs(rb[k]), (k, ra[k], rb[k])
        assert abs(ra["newton_iterations"] - rb["newton_iterations"]) <= 1
    assert fa < fb
