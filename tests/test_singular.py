"""A singular Newton matrix (a motion that nothing holds) is reported: MUMPS's null pivots
(INFOG(28)) per Newton iteration in ``SolveInfo.null_pivots``, a warning when a solve converges
with a singular matrix; none for a well-held body; the null-pivot count looked up through the
condensed solver's inner KSP; 1 and 2 ranks."""

import logging

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact
from fxcontact.materials import LinearElastic
from fxcontact.meshing import BLOCK_TAGS, block
from fxcontact.simulation import Simulation
from fxcontact.newton.solver import NULL_PIVOT_HINT, SolverOptions
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Plane


def _pressed_block(top, linear_solver, material=None, **options):
    """Elastic unit cube (or ``material``) on a frictionless plane (z = 0), its top face moved
    by ``top`` (a scalar: the z component only, so x, y and the rotation about z are free; a
    3-vector: all components held); ``options``: more :class:`SolverOptions`."""
    msh, _, ft = block(MPI.COMM_WORLD, (0, 0, 0), (1, 1, 1), 0.34)
    sp = MixedSpace(msh)
    sim = Simulation(sp, material or LinearElastic(1000.0, 0.3), progress=False,
                     solver_options=SolverOptions(linear_solver=linear_solver, **options))
    f = sim.facets(ft, BLOCK_TAGS["zmax"])
    if np.ndim(top) == 0:
        sim.add_velocity_bc(f, top, 2)
    else:
        sim.add_velocity_bc(f, np.asarray(top, dtype=float))
    sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["zmin"]),
                                     Plane((0, 0, 0), (0, 0, 1), name="anvil")))
    return sim


@pytest.mark.parametrize("linear_solver", ["mumps", "condensed-mumps"])
def test_free_body_is_reported(linear_solver, caplog):
    """x, y translations and the rotation about z are free: null pivots at every Newton
    iteration, and a warning naming the cause once the solve has converged. The count is not
    checked exactly: MUMPS's detection is a threshold test on round-off, and it finds one to
    three of the three free motions depending on the rank count and the BLAS build (three
    serially with one OpenBLAS build, two with another); at least one and never more than the
    three free motions. On 2 ranks it once found none at one iteration of the condensed system
    (``[1, 0]``, in a whole-suite run; not reproduced alone): there at least one iteration
    must find them, and the warning is checked against the last iteration's count (it is given
    when the converged solution's factorisation has null pivots)."""
    sim = _pressed_block(-0.01, linear_solver)
    with caplog.at_level(logging.WARNING, logger="fxcontact.newton.solver"):
        info = sim.step(1.0, max_cutbacks=0).info
    assert info.converged
    assert len(info.null_pivots) == info.iterations
    assert all(0 <= n <= 3 for n in info.null_pivots), info.null_pivots
    if MPI.COMM_WORLD.size == 1:
        assert all(n >= 1 for n in info.null_pivots), info.null_pivots
    else:
        assert any(n >= 1 for n in info.null_pivots), info.null_pivots
    warned = info.null_pivots[-1] > 0
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING
                and "singular" in r.getMessage()]
    assert len(warnings) == int(warned)
    assert all(NULL_PIVOT_HINT in w.getMessage() for w in warnings)
    assert sim.solver.singular_solves == int(warned)


@pytest.mark.parametrize("linear_solver", ["mumps", "condensed-mumps"])
def test_held_body_has_no_null_pivot(linear_solver, caplog):
    sim = _pressed_block([0.0, 0.0, -0.01], linear_solver)
    with caplog.at_level(logging.WARNING, logger="fxcontact.newton.solver"):
        info = sim.step(1.0, max_cutbacks=0).info
    assert info.converged and info.null_pivots and all(n == 0 for n in info.null_pivots)
    assert not [r for r in caplog.records if "singular" in r.getMessage()]
    assert sim.solver.singular_solves == 0


def test_no_count_without_mumps():
    """An iterative solver has no factorisation to ask: the counts are None, no warning."""
    sim = _pressed_block([0.0, 0.0, -0.01], "condensed-amg")
    info = sim.step(1.0, max_cutbacks=0).info
    assert info.null_pivots and all(n is None for n in info.null_pivots)


def _viscoplastic_block(top, reuse):
    """The pressed block of a nearly rigid-plastic Norton–Hoff material (several Newton
    iterations per increment, where ``reuse_factorisation`` keeps factorisations)."""
    from fxcontact.materials import NortonHoff
    return _pressed_block(top, "condensed-mumps", NortonHoff(K=1.0, m=0.1, regularization=1e-3),
                          reuse_factorisation=reuse, prefix=f"sgr_{np.ndim(top)}{reuse}_")


def _factorised_jacobians(sim, n_increments):
    """Run increments; returns the factorisations and Jacobians of the solver (built at the
    first step) and the vertical vertex velocities (the free motions, x, y translations and
    the rotation about z, have none: arbitrary, as MUMPS picks one solution)."""
    from helpers import vertex_velocities_by_position
    pivots = []
    for _ in range(n_increments):
        info = sim.step(0.05, max_cutbacks=0).info
        assert info.converged
        pivots += info.null_pivots
    return (sim.solver.factorisations, sim.solver.callback_calls["jacobian"],
            vertex_velocities_by_position(sim)[:, 2], pivots)


def test_kept_factorisation_never_singular():
    """``reuse_factorisation`` keeps no factorisation that has null pivots: on a free body
    every Jacobian is factorised (a Krylov solve preconditioned by a singular factorisation
    may move far along the null space), and the increments are those without reuse (the
    vertical velocities, which the free motions leave alone, to the Newton tolerance). The
    held body, with the same material, does keep factorisations (the check can fail). Every
    Jacobian is factorised where MUMPS reported the null pivots at every iteration (always
    serially); on 2 ranks its detection, a threshold test on round-off, may miss them at an
    iteration (``test_free_body_is_reported``), and a factorisation it calls regular may be
    kept."""
    fact, jac, w, pivots = _factorised_jacobians(_viscoplastic_block(-0.01, True), 2)
    _, _, w_ref, _ = _factorised_jacobians(_viscoplastic_block(-0.01, False), 2)
    if all(n is not None and n >= 1 for n in pivots):
        assert fact == jac, pivots
    else:
        assert MPI.COMM_WORLD.size > 1 and fact <= jac, pivots
    assert np.isfinite(w).all()
    assert np.linalg.norm(w - w_ref) <= 1e-6 * np.linalg.norm(w_ref)
    fact, jac, _, pivots = _factorised_jacobians(_viscoplastic_block([0.0, 0.0, -0.01], True), 2)
    assert all(n == 0 for n in pivots) and fact < jac, pivots
