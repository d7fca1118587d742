"""Newton on a nearly rigid-plastic Norton–Hoff material (m = 0.016): drawing through a smooth
conical die (``benchmarks/drawing_case.py``), against the classical bounds of the drawing stress
(THEORY §14.2); the die's gap gradient by finite differences."""

import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from helpers import load_file

drawing = load_file("drawing_case", Path(__file__).resolve().parents[1] / "benchmarks" /
                    "drawing_case.py")

R0, REDUCTION, ALPHA, SPEED, K, M = 5.0, 0.15, math.radians(10.0), 10.0, 445.0, 0.016
#: test size: 2.5k dofs, a pull of 0.25 mm (a fifth of the element size at the die) per increment
CASE = dict(R0=R0, reduction=REDUCTION, half_angle_deg=10.0, h=2.5, h_die=1.25, K=K, m=M,
            speed=SPEED)
DT, N_INC = 0.025, 3


def _drawing_bounds():
    """Drawing force [N] from the ideal work (lower bound) and Avitzur's frictionless upper
    bound (THEORY §14.2), with the flow stress at the die's mean strain rate."""
    rate = drawing.mean_strain_rate(R0, REDUCTION, ALPHA, SPEED * (1.0 - REDUCTION))
    sigma0 = math.sqrt(3.0) * K * (math.sqrt(3.0) * rate) ** M
    lnR = -0.5 * math.log(1.0 - REDUCTION)
    s2, c = math.sin(ALPHA) ** 2, math.cos(ALPHA)
    q = math.sqrt(11.0 / 12.0)
    f = (1.0 - c * math.sqrt(1.0 - q * q * s2)
         + math.log((1.0 + q) / (q * c + math.sqrt(1.0 - q * q * s2))) / math.sqrt(132.0)) / s2
    area_f = math.pi * R0**2 * (1.0 - REDUCTION)
    ideal = 2.0 * sigma0 * lnR * area_f
    avitzur = sigma0 * (2.0 * f * lnR + 2.0 / math.sqrt(3.0) * (ALPHA / s2 - 1.0 / math.tan(ALPHA)))
    return ideal, avitzur * area_f


def _run(max_it, max_cutbacks, line_search="bt", line_search_fallback="basic",
         penalty_continuation=None, n_inc=N_INC, active_set_prediction="auto",
         material_tangent="consistent", **kw):
    """The test drawing; by default with the consistent Norton–Hoff tangent (the library's
    default is the primal–dual one, tests/test_dual.py), which these tests compare options on."""
    from fxcontact.newton.solver import SolverOptions

    sim, _, _ = drawing.drawing_simulation(MPI.COMM_WORLD, solver_options=SolverOptions(
        max_it=max_it, line_search=line_search, line_search_fallback=line_search_fallback,
        penalty_continuation=penalty_continuation, active_set_prediction=active_set_prediction,
        material_tangent=material_tangent),
        **{**CASE, **kw})
    for _ in range(n_inc):
        sim.step(DT, max_cutbacks=max_cutbacks)
    its = [r["newton_iterations_all"] for r in sim.history]
    return sim, its


def _check_no_cutback_within_bounds(sim, its, label):
    """No increment was cut back and the last drawing force lies between the ideal-work and
    Avitzur bounds; the Newton counts are printed."""
    F = 4.0 * sim.history[-1]["front_z"]
    lower, upper = _drawing_bounds()
    if MPI.COMM_WORLD.rank == 0:
        print(f"{label}: Newton iterations {its} (mean {np.mean(its):.1f}), force {F:.0f} N, "
              f"bounds [{lower:.0f}, {upper:.0f}] N")
    assert all(r["cutbacks"] == 0 for r in sim.history)
    assert lower < F < upper


def test_die_gap_gradient_and_projection():
    """The die's normal is the gradient of its gap (central differences) and the closest point
    lies on the surface, for points around the cone, the fillet and the bearing."""
    die = drawing.DrawingDie(4.6, ALPHA, 0.0, 4.0)
    rng = np.random.default_rng(3)
    x = np.c_[rng.uniform(3.5, 5.5, 200), rng.uniform(0.0, 2.0, 200), rng.uniform(-5, 3, 200)]
    pr = die.project(x, 0.0, hessian=False)
    e = 1e-6
    grad = np.array([(die.project(x + e * d, 0.0, False).gap
                      - die.project(x - e * d, 0.0, False).gap) / (2 * e) for d in np.eye(3)]).T
    assert np.max(np.abs(grad - pr.normal)) < 1e-7
    assert np.max(np.abs(die.project(pr.point, 0.0, False).gap)) < 1e-12
    # free space is inside: the axis side of the bearing and of the cone
    assert die.project(np.array([[4.0, 0, 1.0], [4.0, 0, -3.0]]), 0.0, False).gap.min() > 0
    assert np.allclose(die.radius([1.0, 0.0]), 4.6)


def test_drawing_m0016_converges_without_cutback_within_classical_bounds():
    """m = 0.016 drawing with the settings that help Newton (benchmarks/README): penalty
    β = 10 (the tangent along the flow is m η, not η) and ε̇₀ = 1e-2 × the die's mean strain
    rate. With the default max_it = 30 every increment converges without cut-back, and the
    drawing force lies between the ideal-work lower bound and Avitzur's upper bound.
    Measured (1 rank): 19, 8, 9 Newton iterations (the first from the rigid start-up guess).
    The bounds on the iteration counts were set with the MINI quadrature of degree 6, which
    this test keeps: with the consistent tangent the counts move with the quadrature points
    (degree 5, the library's default: 18, 12, 14; the default primal–dual tangent takes 10, 6,
    11 at degree 6 and 9, 6, 10 at degree 5, test below)."""
    rate = drawing.mean_strain_rate(R0, REDUCTION, ALPHA, SPEED * (1.0 - REDUCTION))
    sim, its = _run(max_it=30, max_cutbacks=0, beta=10.0, regularization=1e-2 * rate,
                    quadrature_degree=6)
    _check_no_cutback_within_bounds(sim, its, "beta = 10")
    assert np.mean(its) <= 14 and max(its[1:]) <= 12


@pytest.fixture(scope="module")
def default_run():
    """The test drawing with the library's defaults (β = 1e3, ε̇₀ = 1e-6 1/s, bt, active-set
    prediction, primal–dual tangent, MINI quadrature degree 5) and max_it = 30, no cut-back
    allowed: (simulation, Newton iterations per increment) or the IncrementError."""
    from fxcontact.simulation import IncrementError

    try:
        return _run(max_it=30, max_cutbacks=0, material_tangent="auto")
    except IncrementError as e:
        return e


def test_drawing_m0016_default_settings_converge_without_cutback(default_run):
    """With the defaults every increment converges at max_it = 30 without a cut-back (the
    first from the Newtonian start-up guess), the drawing force lies between the ideal-work
    and Avitzur bounds, and the mean Newton count is reported.
    Measured (1 and 2 ranks): 9, 6, 10 (mean 8.3)."""
    if isinstance(default_run, Exception):
        pytest.fail(f"increment failed: {default_run}")
    sim, its = default_run
    _check_no_cutback_within_bounds(sim, its, "default settings")
    assert max(its) <= 15


@pytest.mark.xfail(strict=True, reason=(
    "goal of the issue not reached: mean <= 6 Newton iterations per increment at m = 0.016 "
    "with the default penalty (beta = 1e3), regularisation (1e-6 1/s) and max_it = 30, over "
    "three increments from the start-up. Measured with today's defaults (active-set "
    "prediction and primal-dual Norton-Hoff tangent, bt, MINI quadrature degree 5): 9, 6, "
    "10 (mean 8.3; 10, 6, 11 at degree 6; the first increment starts from the Newtonian "
    "guess, the third has bt-shortened steps, lambda ~ 0.2, with a settled contact set; with "
    "line_search='basic' 9, 6, 7). Other predictors (extrapolated 2 v_n - v_n-1, convected "
    "at x + v dt, projected onto the die) and the consistent tangent near convergence do not "
    "help (bench_predictors.py: 7.8, 11.2, 8.0, 7.6 per increment over five increments "
    "against 7.4). Before (consistent tangent): 60, 31, 40 plain; 36, 12, 12 with the "
    "prediction alone; trust region 35, 28, 25; beta = 10 and a regularisation of 1e-2 x the "
    "mean strain rate: 12, 8, 11. At 7k dofs (bench_newton_rigid_plastic.py, five "
    "increments) the defaults give 7.4 per increment, 6.5 from the second; the thesis-size "
    "wire drawing 6.9"))
def test_drawing_m0016_default_penalty_mean_six_newton_iterations(default_run):
    if isinstance(default_run, Exception):
        pytest.fail(f"increment failed: {default_run}")
    _, its = default_run
    assert np.mean(its) <= 6


# iteration counts only (the trust region runs on 2 ranks in test_assembly and test_wire_drawing)
@pytest.mark.serial
@pytest.mark.slow
def test_drawing_m0016_default_penalty_trust_region_beats_backtracking():
    """With the default penalty (β = 1e3) and regularisation, the trust-region Newton
    (``line_search="trust-region"``) reaches the same solution as the backtracking line search
    in fewer Newton iterations (no fallback, no cut-back) than the plain backtracking one
    (without the active-set prediction, which takes 36, 12, 12: tests/test_prediction.py).
    Measured (1 rank, 2.5k dofs): backtracking 60, 30, 42; trust region 35, 28, 25."""
    sims, its = {}, {}
    for ls in ("bt", "trust-region"):
        sims[ls], its[ls] = _run(max_it=100, max_cutbacks=0, line_search=ls,
                                 line_search_fallback=None, active_set_prediction=False)
        assert all(r["cutbacks"] == 0 for r in sims[ls].history)
    if MPI.COMM_WORLD.rank == 0:
        print(f"Newton iterations: backtracking {its['bt']}, trust region {its['trust-region']}")
    f_bt = [r["front_z"] for r in sims["bt"].history]
    f_tr = [r["front_z"] for r in sims["trust-region"].history]
    assert np.allclose(f_tr, f_bt, rtol=1e-6)
    lower, upper = _drawing_bounds()
    assert lower < 4.0 * f_tr[-1] < upper
    assert sum(its["trust-region"]) < 0.8 * sum(its["bt"])


@pytest.mark.slow
def test_drawing_m0016_penalty_continuation_same_solution_fewer_iterations():
    """Penalty continuation (``SolverOptions.penalty_continuation = 0.03``: each solve first
    with β·0.03 = 30 to a relative residual of 1e-3, then β = 1e3) gives the same solution as
    the plain solve in fewer Newton iterations (both without the active-set prediction).
    ε̇₀ = 1e-2 × the die's mean strain rate.
    Measured (1 rank, 2.5k dofs, two increments): plain 28, 32; continuation 11, 11."""
    rate = drawing.mean_strain_rate(R0, REDUCTION, ALPHA, SPEED * (1.0 - REDUCTION))
    sims, its = {}, {}
    for pc in (None, 0.03):
        sims[pc], its[pc] = _run(max_it=100, max_cutbacks=0, line_search_fallback=None,
                                 penalty_continuation=pc, n_inc=2, active_set_prediction=False,
                                 regularization=1e-2 * rate)
        assert all(r["cutbacks"] == 0 for r in sims[pc].history)
    if MPI.COMM_WORLD.rank == 0:
        print(f"Newton iterations: plain {its[None]}, continuation {its[0.03]}")
    f0 = [r["front_z"] for r in sims[None].history]
    f1 = [r["front_z"] for r in sims[0.03].history]
    assert np.allclose(f1, f0, rtol=1e-6)
    # the penalty is restored after the solves
    contact = sims[0.03].contributors[0]
    assert contact.penalty_scale == 1.0
    assert sum(its[0.03]) < 0.6 * sum(its[None])


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.1, 2.0, float("nan"), "0.1"])
def test_penalty_continuation_bad_factor(bad):
    from fxcontact.newton.solver import SolverOptions

    with pytest.raises(ValueError, match="penalty_continuation"):
        SolverOptions(penalty_continuation=bad)
