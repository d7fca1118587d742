"""What a state-dependent flow stress and the heat cost (THEORY §15, §16).

Usage::

    python benchmarks/bench_flow_heat.py                     # kernels n = 20, drawing size 1
    python benchmarks/bench_flow_heat.py --n 12 --size 0.6 --increments 6
    mpirun -n 2 python benchmarks/bench_flow_heat.py --skip-kernels

Two parts, each ratio taken within one run (the machine may be shared):

* **kernels** (serial; ``--n``: a perturbed unit box of n³ × 6 tetrahedra, MINI, m = 0.016, a
  random state, a dual stress after one update): µs per cell of the hand-written element kernel
  (:class:`~fxcontact.element.tensors.NortonHoffElementTensors`, primal–dual tangent) and of the
  numba dual update for plain ``NortonHoff``, a ``Viscoplastic`` power-hardening law (one rate
  interval) and a table with five rates (four intervals, chosen per quadrature point), and the
  per-increment update of the laws' per-cell pieces from the strain (``LocalNortonHoff.update``);
* **drawing** (the wire-drawing case of ``fxcontact.processes`` at ``--size``, the thesis size
  is 1): the same increments without and with :class:`~fxcontact.WorkpieceHeat` (steel-like
  ρc, k, air, the die at 20 °C): wall time per increment, the heat step's own time
  (``heat_wall``) and its share of the increment, Newton iterations (equal: the plain Norton–Hoff
  law does not read the temperature).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from mpi4py import MPI

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

import dolfinx  # noqa: E402
from _common import best_time  # noqa: E402

import fxcontact as fx  # noqa: E402
from fxcontact.element.dual import DualStress  # noqa: E402
from fxcontact.element.tensors import NortonHoffElementTensors, P1P1Layout  # noqa: E402
from fxcontact.processes import drawing  # noqa: E402


def _table():
    strains = np.array([0.0, 0.5, 1.0, 2.0])
    rates = np.array([0.01, 0.1, 1.0, 10.0, 100.0])
    S = 445.0 * (0.02 + strains) ** 0.1
    g = rates ** 0.016 * (1.0 + 0.01 * np.arange(5))   # m_loc varies by interval
    return fx.TabulatedFlowStress(strains, rates, np.array([20.0]),
                                  S[:, None, None] * g[None, :, None])


def kernel_part(n: int, repeat: int):
    comm = MPI.COMM_SELF
    msh = dolfinx.mesh.create_box(comm, [[0, 0, 0], [1, 1, 1]], [n, n, n],
                                  dolfinx.mesh.CellType.tetrahedron)
    rng = np.random.default_rng(0)
    msh.geometry.x[:, :3] += 0.1 / n * rng.uniform(-1, 1, msh.geometry.x[:, :3].shape) * \
        np.all((msh.geometry.x[:, :3] > 1e-9) & (msh.geometry.x[:, :3] < 1 - 1e-9),
               axis=1)[:, None]
    sp = fx.MixedSpace(msh)
    lay = P1P1Layout(sp.W)
    ncells = msh.topology.index_map(3).size_local
    cells = np.arange(ncells, dtype=np.int32)
    laws = {"NortonHoff": fx.NortonHoff(K=445.0, m=0.016, regularization=1e-3),
            "power hardening": fx.Viscoplastic(fx.PowerHardening(K0=445.0, m=0.016, n=0.1,
                                                                 eps0=0.02), 1e-3),
            "table, 5 rates": fx.Viscoplastic(_table(), 1e-3)}
    strain = rng.uniform(0.0, 1.5, ncells)
    print(f"kernels: {ncells} cells, MINI degree {sp.quadrature_degree}, best of {repeat}")
    print(f"{'law':18s} {'element us/cell':>16s} {'dual us/cell':>13s} "
          f"{'pieces us/cell':>15s}")
    base = None
    for name, law in laws.items():
        mat = law if isinstance(law, fx.NortonHoff) else law.on(sp)
        t_upd = 0.0
        if mat is not law:
            t_upd = best_time(lambda: mat.update(strain), repeat)
        w = dolfinx.fem.Function(sp.W)
        w.x.array[:] = rng.normal(size=w.x.array.shape)
        dual = DualStress(mat, sp.W, sp.quadrature_degree)
        dual.use_kernel(sp)
        dual.begin(w.vector)
        w.x.array[:] += 0.1 * rng.normal(size=w.x.array.shape)
        hand = NortonHoffElementTensors(lay, sp, mat, w, dual)
        hand.tensors(cells[:10])                       # compile
        t_el = best_time(lambda: hand.tensors(cells), repeat)
        t_du = best_time(lambda: dual.accept(w.vector), repeat)
        row = (1e6 * t_el / ncells, 1e6 * t_du / ncells, 1e6 * t_upd / ncells)
        base = base or row
        print(f"{name:18s} {row[0]:10.2f} ({row[0] / base[0]:4.2f}x) {row[1]:7.2f} "
              f"({row[1] / base[1]:4.2f}x) {row[2]:15.3f}")


def drawing_part(size: float, increments: int):
    comm = MPI.COMM_WORLD
    case = drawing.DrawingCase(size=size, stop_at_steady=False)
    out = {}
    for heat in (False, True):
        s = drawing.build(case, comm)
        sim = s.sim
        if heat:
            sim.add_controller(fx.WorkpieceHeat(
                sim, fx.ThermalMaterial(rho_c=2.4, conductivity=150.0), 20.0,
                air=fx.AirExchange(h=0.01, temperature=20.0),
                tools={t.name: fx.ToolHeat(temperature=20.0, h_c=10.0)
                       for t in s.contact.tools}))
        t0 = time.perf_counter()
        sim.run(increments * case.dt, case.dt)
        wall = time.perf_counter() - t0
        rows = sim.history[1:]                        # the first increment compiles
        out[heat] = dict(dofs=s.dofs, wall=np.mean([r["wall_total"] for r in rows]),
                         newton=np.mean([r["newton_iterations"] for r in rows]),
                         heat=np.mean([r.get("heat_wall", 0.0) for r in rows]),
                         T=rows[-1].get("heat_T_max", np.nan), run=wall)
    if comm.rank == 0:
        a, b = out[False], out[True]
        print(f"drawing size {size}: {a['dofs']} dofs, {comm.size} rank(s), {increments} "
              f"increments of {case.dt} s (the first left out)")
        print(f"  without heat: {a['wall']:.3f} s per increment (Newton solve), "
              f"{a['newton']:.2f} Newton its")
        print(f"  with heat:    {b['wall']:.3f} s per increment + heat step {b['heat']:.3f} s "
              f"({100 * b['heat'] / b['wall']:.1f} % of the Newton solve), {b['newton']:.2f} "
              f"Newton its, T max {b['T']:.2f} °C")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--size", type=float, default=1.0)
    ap.add_argument("--increments", type=int, default=4)
    ap.add_argument("--skip-kernels", action="store_true")
    ap.add_argument("--skip-drawing", action="store_true")
    a = ap.parse_args()
    if not a.skip_kernels and MPI.COMM_WORLD.rank == 0:
        kernel_part(a.n, a.repeat)
    MPI.COMM_WORLD.barrier()
    if not a.skip_drawing:
        drawing_part(a.size, a.increments)


if __name__ == "__main__":
    main()
