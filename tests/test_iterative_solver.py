"""The condensed iterative solver (``linear_solver="condensed-amg"``: MINI bubble condensed cell
by cell, FGMRES + Schur field split, GAMG on the velocity block with rigid-body modes) on the
process cases of the solver issue, at test size: Norton–Hoff upsetting with m = 0.015 and
m = 0.3, the Hertz sphere with a contact penalty β = 10⁴, and the wire drawing (fxcontact.processes). Each
converges at every increment and gives the direct solver's (MUMPS on the MINI system) answer
to the Newton tolerance; the Krylov iterations per Newton iteration are printed. (Their growth
with the size, 80k → 1M dofs, is measured in benchmarks/README.md: too large for the suite.)"""


import pytest
from mpi4py import MPI

from fxcontact.processes import upsetting_dies


SOLVERS = ("mumps", "condensed-amg")


def _wire_drawing(solvers):
    from fxcontact.processes import DrawingCase, run_drawing
    case = DrawingCase.quick(t_end=4 * DrawingCase.QUICK["dt"], stop_at_steady=False,
                             max_cutbacks=0)
    return {s: run_drawing(case.replace(linear_solver=s), pictures=False) for s in solvers}


def _check_wire_drawing(res, solver):
    ref, it = res["mumps"].history, res[solver].history
    assert len(it) == len(ref) == 4
    assert all(r["cutbacks"] == 0 for r in it)
    for a, b in zip(it, ref):
        assert abs(a["drawing_force"] - b["drawing_force"]) <= 1e-5 * abs(b["drawing_force"])
        assert a["contact_nodes"] == b["contact_nodes"]
    its = sum(r["newton_iterations_converged"] for r in it)
    k = sum(r["linear_iterations"] for r in it) / its
    assert k > 1
    _say(f"wire drawing (quick), {solver}: Newton its {[r['newton_iterations'] for r in it]} "
         f"(MUMPS {[r['newton_iterations'] for r in ref]}), Krylov/Newton it {k:.1f}")


def _krylov_per_newton(history):
    its = sum(r["newton_iterations"] for r in history)
    return sum(r["linear_iterations"] for r in history) / max(its, 1)


def _say(text):
    if MPI.COMM_WORLD.rank == 0:
        print(text)


@pytest.mark.parametrize("m", [0.015, 0.3])
def test_upsetting(m):
    """Sticking dies, 10 % of the height in 3 increments: the die force and the final shape of
    both solvers agree to 1e-6 (the Krylov tolerance is 1e-8, the Newton tolerance 1e-9)."""
    res = {s: upsetting_dies.run(h=3.0, m=m, n_steps=3, reduction=0.1, output_dir=None,
                                 picture=False, progress=False, linear_solver=s)
           for s in SOLVERS}
    ref, it = res["mumps"], res["condensed-amg"]
    assert len(it["history"]) == len(ref["history"]) == 3
    assert all(r["cutbacks"] == 0 for r in it["history"])
    for a, b in zip(it["history"], ref["history"]):
        assert abs(a["die_z"] - b["die_z"]) <= 1e-6 * abs(b["die_z"]), (a["die_z"], b["die_z"])
    assert abs(it["radius_mid"] - ref["radius_mid"]) <= 1e-9 * ref["radius_mid"]
    k = _krylov_per_newton(it["history"])
    assert k > 1          # the iterative path was taken (MUMPS: one "iteration" per solve)
    _say(f"upsetting m = {m}: Newton its {[r['newton_iterations'] for r in it['history']]} "
         f"(MUMPS {[r['newton_iterations'] for r in ref['history']]}), "
         f"Krylov/Newton it {k:.1f}")


@pytest.mark.slow
def test_hertz_sphere_stiff_penalty():
    """The Hertz sphere (linear elasticity, implicit contact, β = 10⁴): same force and contact
    radius as the direct solver."""
    from fxcontact.processes import hertz_sphere
    kw = dict(h_fine=0.05, growth=0.3, width=20.0, height=20.0, h=4.0, n_steps=2, beta=1e4,
              output_dir=None, picture=False, progress=False)
    res = {s: hertz_sphere.run(linear_solver=s, **kw) for s in SOLVERS}
    ref, it = res["mumps"], res["condensed-amg"]
    assert abs(it["force"] - ref["force"]) <= 1e-6 * abs(ref["force"])
    assert it["contact_radius"] == pytest.approx(ref["contact_radius"], rel=1e-6)
    k = _krylov_per_newton(it["history"])
    assert k > 1
    _say(f"Hertz sphere beta = 1e4: Krylov/Newton it {k:.1f}, force {it['force']:.6g} "
         f"(MUMPS {ref['force']:.6g})")


@pytest.mark.serial    # a known failure: one rank is enough to show it
@pytest.mark.xfail(strict=True, reason=(
    "not met: on the wire-drawing demo (quick size, m = 0.016, K = 445, beta = 100, two "
    "inclined planes) the condensed AMG solve does not converge in 300 FGMRES iterations. "
    "Cause found: the Norton-Hoff tangent acts on the strain-rate deviator, so the velocity "
    "block alone is singular for the dilatation about the pulled front face's centre, which "
    "the velocity conditions leave free (eigenvalue 3e-13 of 9.3e3 in the start-up's "
    "condensed block, the mode v = c (x, y, z - L)); a Schur field split needs that block "
    "invertible. With the (2/3) eta div-div augmentation of the preconditioning matrix "
    "(condensed_augment_scale 1, off by default) and exact inner solves it converges (90 "
    "iterations start-up, 195 main), but with GAMG on the augmented block it still needs "
    "290-300 (condensed-amg-robust, with an inner GMRES on the velocity block and a selfp "
    "Schur preconditioner, converges: next test). Upsetting (m = 0.015, 0.3) and the Hertz "
    "sphere (beta = 1e4) converge"))
@pytest.mark.slow
def test_wire_drawing_demo():
    """The wire-drawing demo at its quick size (m = 0.016, implicit contact with the exact die,
    two inclined symmetry planes, trust-region Newton), four increments: same drawing force
    and contact nodes as the direct solver, no cut-back."""
    _check_wire_drawing(_wire_drawing(SOLVERS), "condensed-amg")


@pytest.mark.slow
def test_wire_drawing_demo_robust_preset():
    """The same with ``"condensed-amg-robust"`` (augmented velocity block, selfp Schur
    preconditioner, inner GMRES on the velocity): it converges where the default preset does
    not."""
    _check_wire_drawing(_wire_drawing(("mumps", "condensed-amg-robust")), "condensed-amg-robust")
