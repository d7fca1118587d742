"""Per-cell cost of the MINI bubble condensed in the element kernel against today's path.

Usage::

    python benchmarks/bench_element_kernel.py                 # box meshes of ~48k and ~304k cells
    python benchmarks/bench_element_kernel.py --n 12 --repeat 5

Case: a unit box of n × n × n × 6 tetrahedra, perturbed, MINI (quadrature degree 5),
Norton–Hoff m = 0.016, a random velocity and pressure state and a dual stress after one
primal–dual update (so the tangent is the primal–dual one with dual ≠ primal stress), 1 process.
Every figure is the best of ``--repeat`` calls, taken in turn within one run, in µs per cell
(the machine may be shared: compare the figures of one run, as ratios):

* ``ffcx J kernel``: FFCx's Jacobian kernel alone, called from numba over the cells (the
  coefficients packed beforehand: ``pack`` is dolfinx's packing of both forms' coefficients);
* ``ffcx J+F + condense``: FFCx's Jacobian and residual kernels and the condensation of the
  bubble in the element (:class:`fxcontact.element.tensors.FFCxElementTensors`);
* ``hand J+F kernel`` and ``hand J+F + condense``: the hand-written Norton–Hoff kernel
  (:class:`~fxcontact.element.tensors.NortonHoffElementTensors`) alone and with the
  condensation;
* ``assemble condensed (ffcx|hand)``: the whole condensed P1/P1 system, insertion into the
  PETSc matrix (AIJ; ``baij``: a block matrix) and vector included
  (:meth:`CondensedAssembler.assemble`, packing included);
* today's path: ``assemble W J`` and ``assemble W F`` (dolfinx's assembly of the full MINI
  Jacobian and residual) and ``CondensedPC condense`` (the condensation work of the condensed
  solver's set-up, :attr:`fxcontact.element.assembled.CondensedPC.times` ``["condense"]``: sub-matrices,
  block inverses, A_lb A_bb⁻¹ A_bl, the update of S; the inner factorisation excluded), and
  their sum ``today: J + F + condense`` against ``assemble condensed``;
* ``dual stress update``: :meth:`fxcontact.element.dual.DualStress.accept` (the Expression evaluation).
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

import dolfinx  # noqa: E402
import dolfinx.fem.petsc  # noqa: E402
from _common import best_time  # noqa: E402

import fxcontact as fx  # noqa: E402
from fxcontact import compat  # noqa: E402
from fxcontact.element import tensors as ec  # noqa: E402
from fxcontact.element.assembled import CondensationLayout, CondensedPC  # noqa: E402
from fxcontact.element.dual import DualStress  # noqa: E402

PREFIX = "bench_ec_"


def case(n: int):
    """Space, material, state, dual stress and the compiled (Jacobian, residual) forms."""
    msh = dolfinx.mesh.create_box(MPI.COMM_WORLD, [[0, 0, 0], [1, 1, 1]], [n, n, n],
                                  dolfinx.mesh.CellType.tetrahedron)
    rng = np.random.default_rng(0)
    x = msh.geometry.x
    x[:] += 0.2 / n * rng.uniform(-1, 1, x.shape) * ((x > 1e-12) & (x < 1 - 1e-12))
    space = fx.MixedSpace(msh)
    mat = fx.NortonHoff(K=1.0, m=0.016, regularization=1e-3)
    w = dolfinx.fem.Function(space.W)
    dual = DualStress(mat, space.W, space.quadrature_degree)
    w.x.array[:] = rng.standard_normal(w.x.array.size)
    dual.begin(w.vector)
    w.x.array[:] += 0.3 * rng.standard_normal(w.x.array.size)
    dual.accept(w.vector)
    a, L = ec.norton_hoff_forms(space, mat, w, dual)
    return space, mat, w, dual, compat.form(a), compat.form(L)


def chunked(fn, ncell, chunk=8192):
    for c0 in range(0, ncell, chunk):
        fn(np.arange(c0, min(c0 + chunk, ncell), dtype=np.int32))


def measure(n: int, repeat: int) -> dict:
    space, mat, w, dual, a, L = case(n)
    lay = ec.P1P1Layout(space.W)
    ncell = lay.num_cells
    ffcx = ec.FFCxElementTensors(lay, a, L)
    hand = ec.NortonHoffElementTensors(lay, space, mat, w, dual)
    asm = {"ffcx": ec.CondensedAssembler(ffcx), "hand": ec.CondensedAssembler(hand)}
    nd = space.W.element.space_dimension
    A1, b1 = np.zeros((nd, nd)), np.zeros(nd)
    data = {"ffcx": ffcx.data(), "hand": hand.data()}
    cells = np.arange(ncell, dtype=np.int32)
    # compilation outside the timings
    for k in ("ffcx", "hand"):
        asm[k].condense(cells[:2], data[k])
    ec._kernel_loop(ffcx.tab_jacobian, data["ffcx"], cells[:2], A1, b1)
    ec._kernel_loop(hand.tab, data["hand"], cells[:2], A1, b1)
    Sc, rc = asm["ffcx"].assemble()
    Sb = lay.create_matrix("baij")
    # today's path
    Aw = dolfinx.fem.petsc.create_matrix(a)
    bw = dolfinx.fem.petsc.create_vector(L)

    def assemble_w_J():
        Aw.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(Aw, a)
        Aw.assemble()

    def assemble_w_F():
        with bw.localForm() as loc:
            loc.set(0.0)
        dolfinx.fem.petsc.assemble_vector(bw, L)
        bw.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)

    assemble_w_J()
    opts = PETSc.Options()
    opts[PREFIX + "ksp_type"] = "preonly"
    opts[PREFIX + "pc_type"] = "none"
    pc = PETSc.PC().create(MPI.COMM_WORLD)
    pc.setType(PETSc.PC.Type.PYTHON)
    cpc = CondensedPC(CondensationLayout(space.W), PREFIX)
    pc.setPythonContext(cpc)
    pc.setOperators(Aw, Aw)
    pc.setUp()   # first set-up: patterns

    def condense_pc():
        before = cpc.times["condense"]
        cpc.setUp(pc)
        return cpc.times["condense"] - before

    def best_condense():
        return min(condense_pc() for _ in range(repeat))

    tasks = {
        "pack": lambda: ffcx.data(),
        "ffcx J kernel": lambda: ec._kernel_loop(ffcx.tab_jacobian, data["ffcx"], cells, A1, b1),
        "ffcx J+F + condense": lambda: chunked(lambda c: asm["ffcx"].condense(c, data["ffcx"]),
                                               ncell),
        "hand J+F kernel": lambda: ec._kernel_loop(hand.tab, data["hand"], cells, A1, b1),
        "hand J+F + condense": lambda: chunked(lambda c: asm["hand"].condense(c, data["hand"]),
                                               ncell),
        "assemble condensed (ffcx)": lambda: asm["ffcx"].assemble(Sc, rc),
        "assemble condensed (hand)": lambda: asm["hand"].assemble(Sc, rc),
        "assemble condensed (hand, baij)": lambda: asm["hand"].assemble(Sb, rc),
        "assemble W J": assemble_w_J,
        "assemble W F": assemble_w_F,
        "dual stress update": lambda: dual.accept(w.vector),
    }
    best = {k: np.inf for k in tasks}
    best["CondensedPC condense"] = np.inf
    for _ in range(repeat):     # the tasks in turn, each run's best kept
        for k, fn in tasks.items():
            best[k] = min(best[k], best_time(fn, 1))
        best["CondensedPC condense"] = min(best["CondensedPC condense"], best_condense())
    for k in ("ksp_type", "pc_type"):
        opts.delValue(PREFIX + k)
    best["today: J + F + condense"] = (best["assemble W J"] + best["assemble W F"]
                                       + best["CondensedPC condense"])
    return {"cells": ncell, "dofs W": space.global_dofs(),
            "dofs P1/P1": lay.Vc.dofmap.index_map.size_global * lay.bs,
            **{k: 1e6 * t / ncell for k, t in best.items()}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[20, 37],
                    help="box subdivisions per side (6 n^3 cells)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    rows = [measure(n, args.repeat) for n in args.n]
    if MPI.COMM_WORLD.rank:
        return rows
    keys = [k for k in rows[0] if k not in ("cells", "dofs W", "dofs P1/P1")]
    print(f"load average: {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores)")
    print(f"{'µs per cell':32s}" + "".join(f"{r['cells']:>12d}" for r in rows))
    for k in ("dofs W", "dofs P1/P1"):
        print(f"{k:32s}" + "".join(f"{r[k]:>12d}" for r in rows))
    for k in keys:
        print(f"{k:32s}" + "".join(f"{r[k]:>12.2f}" for r in rows))
    for r in rows:
        print(f"{r['cells']} cells: today / condensed (hand) = "
              f"{r['today: J + F + condense'] / r['assemble condensed (hand)']:.2f}, "
              f"today / condensed (ffcx) = "
              f"{r['today: J + F + condense'] / r['assemble condensed (ffcx)']:.2f}")
    return rows


if __name__ == "__main__":
    main()
