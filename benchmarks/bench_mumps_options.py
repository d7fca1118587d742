"""MUMPS settings of the condensed P1/P1 system: analysis, factorisation and solve times.

Usage::

    # build the matrices from the wire drawing (2 increments at size 1) and keep them
    python benchmarks/bench_mumps_options.py --size 1.0 --increments 2 --save /tmp/S_size1.dat
    # time the variants on the saved matrices, 1 and 2 ranks
    python benchmarks/bench_mumps_options.py --load /tmp/S_size1.dat
    mpirun -n 2 python benchmarks/bench_mumps_options.py --load /tmp/S_size1.dat
    # self-contained: run and time in one go (also under mpirun)
    python benchmarks/bench_mumps_options.py --size 1.0 --increments 2
    # Newton runs with the preset and with changed options
    python benchmarks/bench_mumps_options.py --size 0.4 --increments 3 --newton mat_mumps_cntl_1=0

The wire drawing of ``demos/demo_wire_drawing.py`` (``run(size=..., t_end=increments x dt)``,
``linear_solver="condensed-mumps"``) is run and, at every set-up of the condensed
preconditioner, the condensed matrix S (the inner KSP's operator) and the right-hand side b of
the first solve with it are copied. ``--matrices k`` of them, evenly spaced over the run (the
last one included), are timed: for every variant (MUMPS options under a prefix of their own,
on top of or instead of the ``condensed-mumps`` preset) a fresh KSP makes the analysis on the
first matrix, then the numerical factorisation and one solve for each matrix, its values copied
into one working matrix (the same nonzero pattern, as in the Newton loop: the analysis is
kept). Times: CPU (``time.process_time``, the maximum over the ranks: on a shared machine the
other processes' load does not inflate it; on 2 ranks it includes MPI's busy waiting) and wall
clocks around ``KSPSetUp`` (the first: analysis + factorisation; the others, the matrix
changed: factorisation, their mean; the analysis is the difference) and ``KSPSolve`` (mean),
the best of ``--repeat`` repetitions, the variants run in turn within each repetition (the
load changes them alike). PETSc's conversion of the matrix for MUMPS is in the set-up times,
as in the Newton loop. Accuracy: the largest
relative residual ‖S x − b‖/‖b‖ over the matrices and the largest relative difference
‖x − x_ref‖/‖x_ref‖ from the preset's solution. MUMPS figures: INFOG(7) (the ordering used,
sequential analysis), INFOG(32) (1 sequential / 2 parallel analysis), INFOG(35) (entries in the
factors after the BLR compression, millions), RINFOG(3) (operations of the elimination),
INFOG(13) (delayed pivots) and INFOG(22) (memory used by the factorisation, total
over the ranks, MB).

Input formats: ``aij`` (the run's matrix), ``sbaij`` (upper triangle), ``baij4``/``sbaij4``
(the unknowns permuted vertex by vertex, (u_x, u_y, u_z, p), block size 4, rows of whole
vertices per rank; the condensed system is in dolfinx's dof order, where the four unknowns of
a vertex are mostly, not always, together), ``aij4`` (the same order in AIJ). ``--newton``
runs the wire drawing with the preset and with changed options and compares the Newton
iterations and the drawing force.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

import petsc4py  # noqa: E402

petsc4py.init(sys.argv[:1])
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

#: the ``condensed-mumps`` preset's inner options (fxcontact.newton.solver.LINEAR_SOLVERS), with the
#: L D Lᵀ factorisation that ``factor_symmetric`` picks for a symmetric S
PRESET = {"ksp_type": "preonly", "pc_type": "cholesky", "pc_factor_mat_solver_type": "mumps",
          "mat_mumps_icntl_14": 200, "mat_mumps_icntl_24": 1}


def variants(ranks: int, full: bool = False):
    """(name, options replacing / adding to PRESET (None: remove), input format). Without
    ``full``, the orderings this MUMPS build lacks (METIS, SCOTCH: it falls back to its
    automatic choice) and three of the BLR settings are left out."""
    v = [("preset (ICNTL 14=200, 24=1)", {}, "aij"),
         ("ICNTL(24)=0", {"mat_mumps_icntl_24": None}, "aij")]
    for name, k in (("AMD", 0), ("AMF", 2), ("SCOTCH", 3), ("PORD", 4), ("METIS", 5),
                    ("QAMD", 6)):
        if full or name not in ("SCOTCH", "METIS"):
            v.append((f"ICNTL(7)={k} {name}", {"mat_mumps_icntl_7": k}, "aij"))
    for name, k in (("PT-SCOTCH", 1), ("ParMETIS", 2)):
        v.append((f"ICNTL(28)=2, ICNTL(29)={k} {name}",
                  {"mat_mumps_icntl_28": 2, "mat_mumps_icntl_29": k}, "aij"))
    v += [("ICNTL(12)=1 usual ordering", {"mat_mumps_icntl_12": 1}, "aij"),
          ("ICNTL(8)=0 no scaling", {"mat_mumps_icntl_8": 0}, "aij"),
          ("CNTL(1)=0 no pivoting", {"mat_mumps_cntl_1": 0.0}, "aij")]
    if ranks > 1:
        v.append(("ICNTL(13)=1 no ScaLAPACK root", {"mat_mumps_icntl_13": 1}, "aij"))
    for k in (1, 2):
        for eps in (1e-12, 1e-10, 1e-8):
            if full or k == 1 or eps == 1e-8:
                v.append((f"BLR ICNTL(35)={k}, CNTL(7)={eps:g}",
                          {"mat_mumps_icntl_35": k, "mat_mumps_cntl_7": eps}, "aij"))
    v += [("LU (unsymmetric MUMPS)", {"pc_type": "lu"}, "aij"),
          ("SBAIJ input", {}, "sbaij"),
          ("LU, BAIJ bs 4 input (vertex order)", {"pc_type": "lu"}, "baij4"),
          ("SBAIJ bs 4 input (vertex order)", {}, "sbaij4"),
          ("AIJ, vertex order", {}, "aij4"),
          ("AIJ, vertex order, ICNTL(15)=-4", {"mat_mumps_icntl_15": -4}, "aij4"),
          # the preset once more, last in each repetition: the spread of the measurement
          ("preset again", {}, "aij")]
    return v


# -- the matrices -------------------------------------------------------------------------
def vertex_order(lay, S):
    """A Vec in S's row layout: the global row of each unknown in the vertex order
    (u_x, u_y, u_z, p vertex by vertex, the rows of each rank kept on it)."""
    from fxcontact import compat

    W = lay.W
    vert = np.full(lay.nown, -1, dtype=np.int64)
    comp = np.full(lay.nown, -1, dtype=np.int64)
    for k in range(lay.gdim):
        vert[lay.vel_nodes[:, k]] = lay.node_vertices
        comp[lay.vel_nodes[:, k]] = k
    Q = W.sub(1)
    cols = [Q.dofmap.dof_layout.entity_dofs(0, i)[0] for i in range(4)]
    pd = compat.dofmap_array(Q)[:, cols].ravel()
    pv = compat.cell_vertices(W.mesh).ravel()
    own = pd < lay.nown
    vert[pd[own]] = pv[own]
    comp[pd[own]] = lay.gdim
    key = vert[lay.retained] * (lay.gdim + 1) + comp[lay.retained]
    if np.any(key < 0) or len(np.unique(key)) != len(key):
        raise RuntimeError("the condensed unknowns are not (velocity, pressure) by vertex")
    if np.any(np.bincount(vert[lay.retained])[np.unique(vert[lay.retained])] != lay.gdim + 1):
        raise RuntimeError("a vertex without its gdim + 1 condensed unknowns")
    rank = np.empty(len(key), dtype=np.int64)
    rank[np.argsort(key, kind="stable")] = np.arange(len(key))
    v = S.createVecLeft()
    v.setArray((S.getOwnershipRange()[0] + rank).astype(float))
    return v


def _drawing(size: float, increments: int, linear_solver, **_ignored) -> dict:
    """The wire drawing (``fxcontact.processes.drawing``) for ``increments`` increments with
    the bubble condensed after the assembly (the matrices this study captures):
    ``{"history", "dofs", "wall"}``."""
    from fxcontact.processes import DrawingCase, run_drawing

    case = DrawingCase(size=size, t_end=increments * DrawingCase.dt, element_condensation=False,
                       linear_solver=linear_solver)     # a preset name or a dict of options
    res = run_drawing(case, output_dir=None, pictures=False)
    return {"history": res.history, "dofs": res.dofs, "wall": res.wall}


def capture(size: float, increments: int, comm):
    """Run the wire drawing; copy (S, b) at every set-up of the condensed PC. Returns the
    pairs, the vertex order (see :func:`vertex_order`) and the counts of analyses and numerical
    factorisations of the run."""
    from fxcontact.element.assembled import CondensedPC
    pairs, seen = [], {"setup": -1, "order": None}
    apply = CondensedPC._apply

    def _apply(self, pc, x, y):
        # the first solve after each set-up: S is the inner operator, b the condensed rhs
        if self.setups != seen["setup"]:
            seen["setup"] = self.setups
            self._condensed_rhs(x)
            S = self.ksp.getOperators()[0]
            pairs.append((S.copy(), self._rl.copy()))
            if seen["order"] is None:
                seen["order"] = vertex_order(self.lay, S)
        apply(self, pc, x, y)

    events = [PETSc.Log.Event(n) for n in ("MatCholFctrSym", "MatCholFctrNum",
                                           "MatLUFactorSym", "MatLUFactorNum")]
    before = [e.getPerfInfo()["count"] for e in events]
    CondensedPC._apply = _apply
    try:
        res = _drawing(size, increments, "condensed-mumps",
                       pictures=False, output_dir=None, comm=comm)
    finally:
        CondensedPC._apply = apply
    counts = {e.getName(): e.getPerfInfo()["count"] - c for e, c in zip(events, before)}
    counts["newton"] = [r["newton_iterations"] for r in res["history"]]
    counts["dofs"] = res["dofs"]
    return pairs, seen["order"], counts


def save(path: str, pairs, order, comm):
    viewer = PETSc.Viewer().createBinary(path, "w", comm=comm)
    n = PETSc.Vec().createMPI((1 if comm.rank == 0 else 0, 1), comm=comm)
    n.set(len(pairs))
    n.view(viewer)
    order.view(viewer)
    for S, b in pairs:
        S.view(viewer)
        b.view(viewer)
    viewer.destroy()


def load(path: str, comm):
    viewer = PETSc.Viewer().createBinary(path, "r", comm=comm)
    n = PETSc.Vec().create(comm=comm)
    n.load(viewer)
    count = int(round(n.sum()))
    order = PETSc.Vec().create(comm=comm)
    order.load(viewer)
    pairs = []
    for _ in range(count):
        S = PETSc.Mat().create(comm=comm)
        S.setType(PETSc.Mat.Type.AIJ)
        S.load(viewer)
        b = PETSc.Vec().create(comm=comm)
        b.load(viewer)
        pairs.append((S, b))
    viewer.destroy()
    # loaded rows and entries are split alike (evenly)
    assert order.getOwnershipRange() == pairs[0][0].getOwnershipRange()
    return pairs, order


def permuted(S: PETSc.Mat, b: PETSc.Vec, order: PETSc.Vec, bs: int):
    """S and b in the vertex order, block size ``bs``, rows of whole vertices on each rank."""
    comm = S.getComm().tompi4py()
    N = S.getSize()[0]
    nv = N // bs
    nloc = bs * (nv // comm.size + (1 if comm.rank < nv % comm.size else 0))
    new = np.rint(order.getArray()).astype(np.int64)
    new_all = np.concatenate(comm.allgather(new))
    ai, aj, av = S.getValuesCSR()
    B = PETSc.Mat().createAIJ(size=((nloc, N), (nloc, N)), bsize=bs, comm=comm)
    width = int(comm.allreduce(int(np.diff(ai).max()), op=MPI.MAX))
    B.setPreallocationNNZ((width, width))
    B.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for i in range(len(ai) - 1):
        cols = new_all[aj[ai[i]:ai[i + 1]]]
        B.setValues(int(new[i]), cols.astype(PETSc.IntType), av[ai[i]:ai[i + 1]])
    B.assemble()
    return B, permuted_vec(b, order, B.createVecLeft())


def permuted_vec(x, order, like4):
    """x (the run's order) in the vertex order of ``like4``'s layout."""
    new = np.rint(order.getArray()).astype(PETSc.IntType)
    y = like4.duplicate()
    y.setValues(new, x.getArray())
    y.assemble()
    return y


# -- the timings ----------------------------------------------------------------------------
class VariantFailed(RuntimeError):
    pass


def _timed(comm, fn):
    """(wall, CPU) seconds of ``fn()``, the maximum over the ranks (the CPU time of this
    process is not inflated by the other processes of a shared machine)."""
    comm.Barrier()
    w0, c0 = time.perf_counter(), time.process_time()
    fn()
    c1 = time.process_time()
    comm.Barrier()
    w1 = time.perf_counter()
    return np.array([w1 - w0, comm.allreduce(c1 - c0, op=MPI.MAX)])


def formats(pairs, order):
    """{format: [(matrix, rhs)]}, the rhs in the matrix's layout."""
    out = {"aij": pairs}
    sb = []
    for S, b in pairs:
        S.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        sb.append((S.convert("sbaij", PETSc.Mat()), b))
    out["sbaij"] = sb
    p4 = [permuted(S, b, order, 4) for S, b in pairs]
    out["aij4"] = p4
    out["baij4"] = [(S.convert("baij", PETSc.Mat()), b) for S, b in p4]
    s4 = []
    for S, b in p4:
        S.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        s4.append((S.convert("sbaij", PETSc.Mat()), b))
    out["sbaij4"] = s4
    return out


def run_variant(prefix, mats, comm):
    """One pass of a variant (its options under ``prefix``) over the matrices ``mats``: a
    fresh KSP, the first set-up (analysis and factorisation), then the values of each other
    matrix copied into the working matrix and its set-up (factorisation only), one solve per
    matrix. Returns the (wall, CPU) times ``first``, ``num`` (mean of the other set-ups),
    ``sym`` = first − num (the analysis), ``solve`` (mean), MUMPS figures and the solutions."""
    W = mats[0][0].duplicate(copy=True)
    ksp = PETSc.KSP().create(comm)
    try:
        ksp.setOptionsPrefix(prefix)
        ksp.setOperators(W, W)
        ksp.setFromOptions()
        xs = []
        t = {"first": 0.0, "num": 0.0, "solve": 0.0}
        for i, (S, b) in enumerate(mats):
            if i:
                S.copy(W, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
                ksp.setOperators(W, W)   # as the condensed PC does at every set-up
            t["num" if i else "first"] = t["num" if i else "first"] + _timed(comm, ksp.setUp)
            F = ksp.getPC().getFactorMatrix()
            if F.getMumpsInfog(1) < 0:
                raise VariantFailed(f"MUMPS INFOG(1) = {F.getMumpsInfog(1)}, INFOG(2) = "
                                    f"{F.getMumpsInfog(2)}")
            x = b.duplicate()
            t["solve"] = t["solve"] + _timed(comm, lambda: ksp.solve(b, x))
            if ksp.getConvergedReason() < 0:
                raise VariantFailed(f"KSP reason {ksp.getConvergedReason()}")
            xs.append(x)
        t["num"] = t["num"] / max(1, len(mats) - 1)
        t["solve"] = t["solve"] / len(mats)
        t["sym"] = t["first"] - t["num"]
        f35 = F.getMumpsInfog(35)      # entries in the factors after the BLR compression
        info = dict(ordering=F.getMumpsInfog(7), analysis=F.getMumpsInfog(32),
                    factors=(-f35 if f35 < 0 else f35 / 1e6),
                    memory=F.getMumpsInfog(22), null_pivots=F.getMumpsInfog(28),
                    flops=F.getMumpsRinfog(3) / 1e9, delayed=F.getMumpsInfog(13))
    finally:
        ksp.destroy()
        W.destroy()
    return t, info, xs


def accuracy(mats, xs, refs):
    res = dif = 0.0
    for (S, b), x, xr in zip(mats, xs, refs):
        r = b.duplicate()
        S.mult(x, r)
        r.axpy(-1.0, b)
        res = max(res, r.norm() / b.norm())
        d = x.copy()
        d.axpy(-1.0, xr)
        dif = max(dif, d.norm() / xr.norm())
    return res, dif


ORDERINGS = {0: "AMD", 1: "given", 2: "AMF", 3: "SCOTCH", 4: "PORD", 5: "METIS", 6: "QAMD"}


def newton_check(size: float, increments: int, change: dict, comm, say):
    """The wire drawing with the ``condensed-mumps`` preset and with ``change`` (options of
    the condensed system without prefix, None removes one): Newton iterations, drawing force
    and linear-solve time per increment."""
    from fxcontact.newton.solver import LINEAR_SOLVERS
    out = {}
    preset = LINEAR_SOLVERS["condensed-mumps"]
    changed = {k: v for k, v in {**preset, **{"condensed_" + k: v for k, v in change.items()}
                                 }.items() if v is not None}
    for label, lin in (("preset", dict(preset)), ("changed", changed)):
        res = _drawing(size, increments, lin,
                       pictures=False, output_dir=None, comm=comm)
        h = res["history"]
        out[label] = h
        say(f"{label}: Newton iterations {[r['newton_iterations'] for r in h]}, drawing "
            f"force {[round(r['drawing_force'], 6) for r in h]}, linear solve "
            f"{sum(r['wall_linear_solve'] for r in h):.1f} s of {res['wall']:.1f} s")
    a, b = out["preset"][-1]["drawing_force"], out["changed"][-1]["drawing_force"]
    say(f"relative difference of the last drawing force {abs(b - a) / abs(a):.1e}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=float, default=1.0, help="wire drawing size (demo's size)")
    ap.add_argument("--increments", type=int, default=2, help="increments of the run")
    ap.add_argument("--load", help="PETSc binary file written by --save (no run)")
    ap.add_argument("--save", help="write the captured matrices to this file")
    ap.add_argument("--matrices", type=int, default=3, help="matrices timed per variant")
    ap.add_argument("--repeat", type=int, default=3, help="repetitions (the best is kept)")
    ap.add_argument("--only", action="append", default=[],
                    help="run only the variants whose name contains this text (repeatable; "
                    "the preset always runs)")
    ap.add_argument("--all", action="store_true", help="also the orderings this MUMPS lacks "
                    "(METIS, SCOTCH) and all six BLR settings")
    ap.add_argument("--capture-only", action="store_true", help="run, save, do not time")
    ap.add_argument("--newton", metavar="KEY=VALUE,...",
                    help="no timing of the factorisation: run the wire drawing with the preset "
                    "and with these condensed-system options (without prefix, e.g. "
                    "mat_mumps_icntl_7=0; VALUE none removes the preset's option) and compare "
                    "the Newton iterations and the drawing force")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    PETSc.Log.begin()
    say = (lambda *a: print(*a, flush=True)) if comm.rank == 0 else (lambda *a: None)
    if args.newton is not None:
        import fxcontact as fx
        fx.configure_logging(verbose=False, quiet=True)
        change = {}
        for kv in filter(None, args.newton.split(",")):
            k, v = kv.split("=", 1)
            change[k] = None if v.lower() == "none" else v
        newton_check(args.size, args.increments, change, comm, say)
        return
    if args.load:
        pairs, order = load(args.load, comm)
    else:
        import fxcontact as fx
        fx.configure_logging(verbose=False, quiet=True)
        pairs, order, counts = capture(args.size, args.increments, comm)
        say(f"run: {counts['dofs']} dofs, Newton iterations {counts['newton']}; condensed "
            f"set-ups {len(pairs)}; analyses {counts['MatCholFctrSym']} (LU "
            f"{counts['MatLUFactorSym']}), numerical factorisations "
            f"{counts['MatCholFctrNum']} (LU {counts['MatLUFactorNum']})")
        if args.save:
            save(args.save, pairs, order, comm)
            say(f"saved {len(pairs)} matrices to {args.save}")
        if args.capture_only:
            return
    k = min(args.matrices, len(pairs))
    pick = sorted({int(round(j)) for j in np.linspace(len(pairs) - 1, 0, k)})
    pairs = [pairs[j] for j in pick]
    S0 = pairs[0][0]
    say(f"condensed S: {S0.getSize()[0]} unknowns, {int(S0.getInfo()['nz_used'])} nonzeros "
        f"(AIJ), matrices {pick} of the run, {comm.size} rank(s), best of {args.repeat}; "
        f"load average {os.getloadavg()[0]:.1f}")
    mats = formats(pairs, order)
    opts = PETSc.Options()
    todo = []
    for tag, (name, change, fmt) in enumerate(variants(comm.size, args.all)):
        if tag and args.only and not any(s in name for s in args.only):
            continue
        for k, v in {**PRESET, **change}.items():
            if v is not None:
                opts.setValue(f"bench{tag}_{k}", v)
        todo.append((tag, name, fmt))
    # round robin: every repetition runs all the variants, so that the load of the machine
    # (shared) changes all alike; the best of the repetitions is kept
    best, found, failed = {}, {}, {}
    for rep in range(args.repeat):
        for tag, name, fmt in todo:
            if tag in failed:
                continue
            try:
                t, info, xs = run_variant(f"bench{tag}_", mats[fmt], comm)
            except (PETSc.Error, VariantFailed) as err:
                failed[tag] = str(err).splitlines()[-1]
                say(f"{name}: failed ({failed[tag]})")
                continue
            best[tag] = t if tag not in best else {k: np.minimum(best[tag][k], t[k])
                                                   for k in t}
            found[tag] = (info, xs)
        say(f"repetition {rep + 1} done, load average {os.getloadavg()[0]:.1f}")
    refs = {"aij": found[0][1], "sbaij": found[0][1]}
    refs["aij4"] = refs["baij4"] = refs["sbaij4"] = [
        permuted_vec(x, order, m[1]) for x, m in zip(found[0][1], mats["aij4"])]
    rows = []
    for tag, name, fmt in todo:
        if tag in failed:
            rows.append((name, None, failed[tag], None, None))
            continue
        info, xs = found[tag]
        t = {k: v for k, v in best[tag].items()}
        t["sym"] = t["first"] - t["num"]
        res, dif = accuracy(mats[fmt], xs, refs[fmt])
        rows.append((name, t, info, res, dif))
        say(f"{name}: analysis {t['sym'][1]:.3f} s, factorisation {t['num'][1]:.3f} s, solve "
            f"{t['solve'][1]:.4f} s (CPU; wall {t['sym'][0]:.3f}, {t['num'][0]:.3f}, "
            f"{t['solve'][0]:.4f}); residual {res:.1e}, "
            f"|x - x_preset| {dif:.1e}; ordering {ORDERINGS.get(info['ordering'], '?')}, "
            f"analysis {'parallel' if info['analysis'] == 2 else 'sequential'}, factors "
            f"{info['factors']:.2f} M, {info['flops']:.2f} GFlop, memory {info['memory']} MB, "
            f"null pivots {info['null_pivots']}, delayed pivots {info['delayed']}")
    base = rows[0][1]
    say("")
    say("CPU seconds (maximum over the ranks), the factorisation's wall time beside it; ratios "
        "of CPU times")
    say("")
    say("| variant | analysis s | factorisation s (wall) | solve s | fact. / preset | "
        "ana.+fact. / preset | ‖Sx−b‖/‖b‖ | ‖x−x₀‖/‖x₀‖ | ordering | factors M | GFlop | "
        "MB |")
    say("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, t, info, res, dif in rows:
        if t is None:
            say(f"| {name} | failed: {info} | | | | | | | | | | |")
            continue
        c = {k: v[1] for k, v in t.items()}
        c0 = {k: v[1] for k, v in base.items()}
        say(f"| {name} | {c['sym']:.3f} | {c['num']:.3f} ({t['num'][0]:.3f}) | "
            f"{c['solve']:.4f} | {c['num'] / c0['num']:.2f} | "
            f"{(c['sym'] + c['num']) / (c0['sym'] + c0['num']):.2f} | {res:.1e} | "
            f"{dif:.1e} | {ORDERINGS.get(info['ordering'], '?')}"
            f"{' (par.)' if info['analysis'] == 2 else ''} | {info['factors']:.2f} | "
            f"{info['flops']:.1f} | {info['memory']} |")
    say(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
