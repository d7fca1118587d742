"""Viscoplasticity with a state-dependent flow stress (THEORY §15) in the simulation: the hand
kernel and the numba dual update against the UFL forms and expressions with the same law, and
frictionless homogeneous compression against σ₀(ε̄, ε̄̇) V/h."""

import dataclasses

import dolfinx
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

import fxcontact as fx
from fxcontact import compat
from fxcontact.collective import digest
from fxcontact.element.dual import DualStress, dual_update_numpy
from fxcontact.element.tensors import (FFCxElementTensors, NortonHoffElementTensors, P1P1Layout,
                                        norton_hoff_forms, norton_hoff_tensors_numpy)
from helpers import box_mesh
from test_element_condense import _max_rel, set_state
from test_mechanics import _faces


def table_law():
    """A table whose rate sensitivity changes from one rate interval to the next (m 0.05 to
    0.3), hardening in ε̄ and softening in T."""
    strains = np.array([0.0, 0.2, 0.5, 1.0])
    rates = np.array([0.05, 0.5, 1.5, 5.0, 50.0])
    temps = np.array([20.0, 400.0])
    g = np.array([1.0, 1.12, 1.5, 1.7, 2.3])        # σ₀ against the rate nodes
    S = 80.0 * (0.05 + strains) ** 0.2
    stress = S[:, None, None] * g[None, :, None] * np.array([1.0, 0.7])[None, None, :]
    return fx.TabulatedFlowStress(strains, rates, temps, stress)


LAWS = {"power": lambda: fx.Viscoplastic(fx.PowerHardening(K0=60.0, m=0.1, n=0.25, eps0=0.02),
                                         regularization=1e-2),
        "table": lambda: fx.Viscoplastic(table_law(), regularization=1e-2, temperature=150.0)}


def _state_case(law, comm=MPI.COMM_WORLD):
    """A distorted box with a sheared velocity, a strain varying over the cells and a dual
    stress reached by one update (≠ the primal stress)."""
    msh = box_mesh(comm, n=(4, 4, 4), perturb=0.25)
    sp = fx.MixedSpace(msh)
    mat = LAWS[law]().on(sp)
    imap = msh.topology.index_map(3)
    mid = dolfinx.mesh.compute_midpoints(
        msh, 3, np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32))
    strain = np.zeros(mat.fields.K_cells.shape[0])
    strain[mat.fields.cell_dofs] = 0.8 * mid[:, 0] * mid[:, 1] + 0.3 * mid[:, 2]
    mat.update(strain)
    lay = P1P1Layout(sp.W)
    w = dolfinx.fem.Function(sp.W)
    return sp, mat, lay, w


@pytest.mark.parametrize("law", sorted(LAWS))
def test_hand_kernel_equals_ufl_with_a_state_law(law):
    """Element matrices and vectors of the hand kernel (numba and its numpy twin) equal FFCx's
    forms of the same law (DG0 pieces, conditionals between rate intervals) to 1e-10, with the
    primal-dual tangent and the consistent one; the quadrature points fall in several rate
    intervals and the cells have different strains."""
    sp, mat, lay, w = _state_case(law)
    dual = DualStress(mat, sp.W, sp.quadrature_degree)
    set_state(lay, w)
    dual.begin(w.vector)
    set_state(lay, w, phase=0.7)
    dual.accept(w.vector)
    g = dolfinx.fem.Constant(sp.mesh, PETSc.ScalarType(0.05))
    cells = np.arange(lay.num_cells, dtype=np.int32)
    for d in (dual, None):
        J, F = norton_hoff_forms(sp, mat, w, d, pressure_source=g)
        A_f, b_f = FFCxElementTensors(lay, compat.form(J), compat.form(F)).tensors(cells)
        hand = NortonHoffElementTensors(lay, sp, mat, w, d, pressure_source=0.05)
        A_h, b_h = hand.tensors(cells)
        args = hand.inputs(cells)
        A_n, b_n = norton_hoff_tensors_numpy(*args)
        assert _max_rel(A_h, A_f) <= 1e-10 and _max_rel(b_h, b_f) <= 1e-10
        assert _max_rel(A_n, A_h) <= 1e-12 and _max_rel(b_n, b_h) <= 1e-12
    if law == "table":   # the check covers the interval choice: several intervals are used
        coords, wv, _, K, m, eps0, _, (gref, _, _), zn = args
        J_ = np.transpose(coords[:, 1:] - coords[:, :1], (0, 2, 1))
        G = np.einsum("qak,nkj->nqaj", gref, np.linalg.inv(J_))
        L = np.einsum("nai,nqaj->nqij", wv[:, :15].reshape(-1, 5, 3), G)
        e = 0.5 * (L + np.swapaxes(L, -1, -2))
        e -= np.trace(e, axis1=-2, axis2=-1)[..., None, None] / 3.0 * np.eye(3)
        z = np.sqrt(2.0 * np.einsum("nqij,nqij->nq", e, e) + 3.0 * eps0**2)
        used = np.unique(np.searchsorted(zn, z, side="right"))
        assert MPI.COMM_WORLD.allreduce(len(used), op=MPI.MAX) >= 2, used
    # the cells' laws differ (the strain enters)
    assert np.ptp(mat.fields.K_cells[:, 0]) > 0.01 * mat.fields.K_cells[:, 0].max()
    # the set-up compared between ranks sees the law, not the rank's cells
    assert len(set(MPI.COMM_WORLD.allgather(digest(mat)))) == 1


@pytest.mark.parametrize("law", sorted(LAWS))
def test_dual_kernel_equals_the_expressions_with_a_state_law(law):
    """The numba dual update with per-cell pieces against dolfinx's evaluation of the UFL
    expressions and against its numpy twin, over a primal start and three updates."""
    sp, mat, lay, w = _state_case(law)
    ref = DualStress(mat, sp.W, sp.quadrature_degree)
    fast = DualStress(mat, sp.W, sp.quadrature_degree)
    assert fast.use_kernel(sp)
    kern = fast.kernel
    cells = np.arange(lay.num_cells)
    K, m, zn = mat.kernel_law(kern._xdofs.shape[0])
    for k, phase in enumerate([0.0, 0.4, 1.1, -0.7]):
        set_state(lay, w, phase)
        s_before = fast.s.x.array.copy()
        w_before = fast._w_new.x.array.copy()
        for ds in (ref, fast):
            (ds.begin if k == 0 else ds.accept)(w.vector)
        a = fast.s.x.array.reshape(-1, 3, 3)
        b = ref.s.x.array.reshape(-1, 3, 3)
        scale = np.abs(b).max()
        assert np.abs(a - b).max() <= 1e-11 * scale
        blocks = kern._sdofs[cells]
        tw = dual_update_numpy(kern._x[kern._xdofs[cells]], w_before[kern._wdofs[cells]],
                               w.x.array[kern._wdofs[cells]],
                               s_before.reshape(-1, 3, 3)[blocks], K[cells], m[cells],
                               mat.regularization, kern.g1, kern.gb, kern.share,
                               0 if k == 0 else 1, z_nodes=zn)
        assert np.abs(tw - a[blocks]).max() <= 1e-11 * scale


def compress(comm, material, v=0.1, h0=1.0, dt=0.2, n_inc=12, setup=None):
    """A block compressed at constant die speed ``v`` [mm/s] between frictionless plates
    (sliding on symmetry faces): homogeneous flow, which the MINI element represents exactly.
    Returns the simulation, the initial volume and per increment (h and the volume at its
    start, the plate force). ``setup(sim)`` adds to the simulation before the first step."""
    L = (1.0, 1.0, h0)
    msh = box_mesh(comm, L, (2, 2, 2), perturb=0.1)
    # without volume correction the flow of each increment is isochoric: ε̄̇ = v/h exactly
    sim = fx.Simulation(fx.MixedSpace(msh), material, progress=False, volume_correction="none")
    f = _faces(msh, L)
    sim.add_velocity_bc(f["x0"], 0.0, 0)
    sim.add_velocity_bc(f["y0"], 0.0, 1)
    sim.add_velocity_bc(f["z0"], 0.0, 2)
    sim.add_velocity_bc(f["z1"], -v, 2)
    sim.add_reaction("top", f["z1"])
    if setup is not None:
        setup(sim)
    out = []
    V0 = sim.volume()
    for i in range(n_inc):
        h, vol = h0 - v * sim.t, sim.volume()
        sim.step(dt)
        out.append((h, -sim.history[-1]["top_z"], vol))
    return sim, V0, out


@pytest.mark.parametrize("law", sorted(LAWS))
def test_homogeneous_compression_with_hardening(law):
    """THEORY §15 check: frictionless compression at constant speed, F = σ₀(ε̄, ε̄̇, T) V/h at
    every increment. Against the discrete state (ε̄ summed over the increments, taken at the
    start of each: explicit in the state, implicit in the rate) to 1e-6; against the exact
    ε̄ = ln(h₀/h) within 0.5 % (the first-order error of the state, O(dt) per increment). The
    rate v/h crosses rate nodes of the table during the run."""
    mat = dataclasses.replace(LAWS[law](), regularization=1e-6)   # ε̇₀ ≪ v/h
    v, h0, dt = (0.45, 1.0, 0.05) if law == "table" else (0.1, 1.0, 0.2)
    sim, V0, out = compress(MPI.COMM_WORLD, mat, v=v, h0=h0, dt=dt)
    T = 20.0 if mat.temperature is None else mat.temperature
    eps_sum = 0.0
    rates = []
    for h, F, vol in out:
        rate = v / h
        rates.append(rate)
        exact = mat.flow.sigma0(np.log(h0 / h), rate, T) * vol / h
        discrete = mat.flow.sigma0(eps_sum, rate, T) * vol / h
        assert abs(F / discrete - 1.0) < 1e-6, (h, F, discrete)
        assert abs(F / exact - 1.0) < 5e-3, (h, F, exact)
        eps_sum += dt * rate
    # the simulation's own strain field is the discrete state
    assert np.allclose(sim.strain.x.array, eps_sum, rtol=1e-8)
    if law == "table":
        nodes = mat.flow.rate_nodes
        assert np.any((nodes > min(rates)) & (nodes < max(rates)))


def test_viscoplastic_bad_input():
    """A T-dependent law without a temperature, a wrong flow object, a bad regularisation."""
    with pytest.raises(ValueError, match="temperature"):
        fx.Viscoplastic(table_law())
    with pytest.raises(ValueError, match="flow-stress law"):
        fx.Viscoplastic(fx.NortonHoff(K=10.0, m=0.2))
    with pytest.raises(ValueError, match="regularization"):
        fx.Viscoplastic(fx.PowerHardening(K0=60.0, m=0.1), regularization=-1.0)
    with pytest.raises(ValueError, match="temperature"):
        fx.Viscoplastic(table_law(), temperature=float("nan"))
