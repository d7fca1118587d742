"""Where a Newton iteration's assembly time goes on the wire drawing, before/after each change.

Usage::

    python benchmarks/bench_assembly.py                      # size 0.4 (12.4k dofs), 0.01 s
    python benchmarks/bench_assembly.py --size 0.25 --t_end 0.0125 --repeat 2
    python benchmarks/bench_assembly.py --skip-newton        # the kernel figures only

Case: the wire drawing of :mod:`fxcontact.processes` (MINI P1+bubble/P1, Norton–Hoff m = 0.016, quadrature
degree 6, implicit contact on the exact die, two symmetry planes), 1 process.

**Kernel** (one Jacobian / residual assembly at a random velocity, best of ``--best``): time
per cell of the generated kernels with dolfinx's compiler flags (``-O2 -g0``) and with
fxcontact's (:data:`fxcontact.compat.JIT_EXTRA_COMPILE_ARGS`, ``-fno-math-errno``), and the
same assembly with empty kernels (FFCx ``tabulate_tensor_void``: the cost of the assembly loop
and of the matrix insertion); quadrature points; ``pow``/``sqrt`` calls and an approximate count
of the floating-point operations of the generated C (operators of every statement times the
trip counts of its loops; index arithmetic not counted); whether the element tensors are
bitwise equal between the flag sets.

**Newton** (the demo's increments, the first one — JIT and numba compilation — not timed): one
fresh run per variant, each switching one change on after the other:

* ``before``: dolfinx's compiler flags, the residual always lifted;
* ``+no-errno``: the kernels compiled with ``-fno-math-errno``;
* ``+no-zero-lift``: also the residual lifting skipped when it is exactly zero
  (:attr:`fxcontact.newton.problem.NonlinearProblem.skip_zero_lifting`): every variant after this one is
  the library's default.

Per Newton iteration: residual and Jacobian evaluations (SNES callbacks), their UFL assembly
time (``SolveInfo.times["assembly_residual"]``, ``["assembly_jacobian"]``), contact, the
callbacks' Python overhead (callback time − assembly − contact: copy of the iterate, ghost
update, contributors' collectives), linear solve, other, total; and the largest difference of
the drawing force and of the final velocities from ``before`` (the changes are exact: 0 or
round-off), the Newton iterations of each run. ``--repeat n`` runs the variants n times in
turn and keeps each one's fastest run (the machine may be shared).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time

import numpy as np
from mpi4py import MPI

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

import dolfinx  # noqa: E402
import dolfinx.fem.petsc  # noqa: E402
import dolfinx.jit  # noqa: E402
import ufl  # noqa: E402

import fxcontact as fx  # noqa: E402
import fxcontact.newton.problem as fxpetsc  # noqa: E402
import fxcontact.simulation as fxsim  # noqa: E402
from fxcontact import compat  # noqa: E402
from fxcontact.processes import DrawingCase, run_drawing  # noqa: E402

VARIANTS = (("before", dict(flags=False, skip_lift=False)),
            ("+no-errno", dict(flags=True, skip_lift=False)),
            ("+no-zero-lift", dict(flags=True, skip_lift=True)))

_FOR = re.compile(r"for \(int (\w+) = 0; \1 < (\d+); \+\+\1\)")


def count_flops(code: str, function: str):
    """Approximate floating-point operations and math calls of one generated C function:
    ``+ - * /`` of every statement (contents of ``[...]`` removed: index arithmetic) times the
    trip counts of the enclosing ``for`` loops. Returns (flops, {call: count})."""
    start = code.index(function)
    body = code[code.index("{", start):]
    flops, calls = 0, {"pow": 0, "sqrt": 0}
    stack, pending, depth = [], None, 0
    for line in body.splitlines():
        s = line.strip()
        m = _FOR.match(s)
        if m:
            pending = int(m.group(2))
            continue
        if s == "{":
            depth += 1
            stack.append(pending or 1)
            pending = None
            continue
        if s == "}":
            depth -= 1
            stack.pop()
            if depth == 0:
                break
            continue
        mult = int(np.prod(stack)) * (pending or 1)
        if pending is not None and s.endswith(";"):
            pending = None            # single-statement loop body
        if "=" not in s or s.startswith(("const", "static")) and "[" in s.split("=")[0] \
                and "{" in s:
            continue                  # tables
        stmt = re.sub(r"\[[^\]]*\]", "", s.split("=", 1)[1] if "=" in s else s)
        stmt = re.sub(r"\de[-+]\d", "", stmt)                   # exponents of literals
        n_ops = len(re.findall(r"(?<![eE(])[-+*/](?!=)", stmt))
        if re.search(r"\+=|-=|\*=", s):
            n_ops += 1
        flops += n_ops * mult
        for c in calls:
            calls[c] += len(re.findall(rf"\b{c}\(", s)) * mult
    return flops, calls


def _generated_c(comm, form, flags) -> str:
    """The C source FFCx generated for ``form`` (from the JIT cache if it was compiled)."""
    _, module, (_, code) = dolfinx.jit.ffcx_jit(comm, form,
                                                jit_params={"cffi_extra_compile_args": flags})
    if code is None:
        path = module.__file__     # <cache>/libffcx_forms_<hash>.cpython-*.so
        src = os.path.join(os.path.dirname(path), os.path.basename(path).split(".")[0] + ".c")
        with open(src) as f:
            code = f.read()
    return code


def _kernel_functions(code: str):
    return re.findall(r"void (tabulate_tensor_integral_\w+)\(", code)


def kernel_figures(size: float, best: int):
    """Time per cell of the Jacobian/residual kernels under each set of compiler flags."""
    case = DrawingCase(size=size)
    g = case.layout()
    comm = MPI.COMM_WORLD
    msh, _, _ = fx.drawing_bar(comm, case.R0, case.length, g.h, nose_length=g.nose_length,
                               nose_radius=g.nose_radius, nose_angle=case.alpha,
                               sector=case.sector)
    space = fx.MixedSpace(msh)
    ncell = msh.topology.index_map(3).size_local
    mat = fx.NortonHoff(K=case.K, m=case.m, regularization=1e-3)
    w = dolfinx.fem.Function(space.W)
    w.x.array[:] = np.random.default_rng(1).normal(size=w.x.array.size)
    v, p = ufl.split(w)
    wt, q = ufl.TestFunctions(space.W)
    F = mat.residual(v, p, wt, q, space.dx, 1.0)
    J = ufl.derivative(F, w, ufl.TrialFunction(space.W))
    import basix
    nq = len(basix.make_quadrature(basix.CellType.tetrahedron, space.quadrature_degree)[1])
    base = list(dolfinx.jit.get_parameters()["cffi_extra_compile_args"])
    flag_sets = {"dolfinx": base, "fxcontact": compat.jit_params()["cffi_extra_compile_args"]}
    print(f"\n## Kernel: {ncell} cells, {space.global_dofs()} dofs, quadrature degree "
          f"{space.quadrature_degree}: {nq} points per tetrahedron (basix {basix.__version__})")
    # operation counts from the generated C (the same for every flag set)
    code = _generated_c(comm, J, base)
    fJ, cJ = count_flops(code, _kernel_functions(code)[0])
    code = _generated_c(comm, F, base)
    fF, cF = count_flops(code, _kernel_functions(code)[0])
    print(f"generated C per cell (approximate): Jacobian {fJ / 1e3:.0f} kflop, "
          f"{cJ['pow']} pow + {cJ['sqrt']} sqrt calls ({cJ['pow'] // nq} pow per point); "
          f"residual {fF / 1e3:.0f} kflop, {cF['pow']} pow + {cF['sqrt']} sqrt calls")
    rows, arrays = [], {}
    variants = list(flag_sets.items()) + [("empty kernels", None)]
    for name, flags in variants:
        if flags is None:
            fcp = {"tabulate_tensor_void": True}
            jp = {"cffi_extra_compile_args": base}
        else:
            fcp, jp = {}, {"cffi_extra_compile_args": flags}
        Lf = dolfinx.fem.form(F, form_compiler_params=fcp, jit_params=jp)
        af = dolfinx.fem.form(J, form_compiler_params=fcp, jit_params=jp)
        A = dolfinx.fem.petsc.create_matrix(af)
        b = dolfinx.fem.petsc.create_vector(Lf)
        tj, tf = _best_matrix_time(A, af, best), np.inf
        for _ in range(best):
            t0 = time.perf_counter()
            with b.localForm() as bl:
                bl.set(0.0)
            dolfinx.fem.petsc.assemble_vector(b, Lf)
            tf = min(tf, time.perf_counter() - t0)
        arrays[name] = (A.getValuesCSR()[2].copy(), b.getArray().copy())
        rows.append((name, " ".join(flags) if flags else "-", tj, tf))
        A.destroy()
        b.destroy()
    same = all(np.array_equal(arrays["dolfinx"][k], arrays["fxcontact"][k]) for k in (0, 1))
    empty = rows[-1]
    print("| flags | C flags | Jacobian ms (µs/cell) | kernel share | residual ms (µs/cell) |")
    print("|---|---|---|---|---|")
    for name, flags, tj, tf in rows:
        share = "" if name == "empty kernels" else f"{(tj - empty[2]) / tj:.0%}"
        print(f"| {name} | `{flags}` | {tj * 1e3:.1f} ({tj / ncell * 1e6:.1f}) | {share} | "
              f"{tf * 1e3:.1f} ({tf / ncell * 1e6:.2f}) |")
    print(f"element tensors of the two flag sets bitwise equal: {same}")
    primal_dual_figures(mat, space, w, F, ncell, best)
    quadrature_figures(msh, mat, ncell, best)
    return same


def _best_matrix_time(A, form, best: int) -> float:
    """Fastest of ``best`` assemblies of ``form`` into ``A`` [s]."""
    t = np.inf
    for _ in range(best):
        t0 = time.perf_counter()
        A.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(A, form)
        A.assemble()
        t = min(t, time.perf_counter() - t0)
    return t


def primal_dual_figures(mat, space, w, F, ncell: int, best: int):
    """The primal–dual Jacobian (fxcontact.element.dual, the default for m < 1) two ways, fxcontact's
    flags, at a random dual stress: UFL's derivative plus the correction form, and the tangent
    written out (DualStress.tangent_form + the pressure terms: what Simulation assembles); the
    consistent Jacobian for reference. Time per cell and the largest relative difference."""
    from fxcontact.element.dual import DualStress
    v, p = ufl.split(w)
    wt, q = ufl.TestFunctions(space.W)
    dw = ufl.TrialFunction(space.W)
    dv, dp = ufl.split(dw)
    ds = DualStress(mat, space.W, space.quadrature_degree)
    ds.s.x.array[:] = np.random.default_rng(2).normal(size=ds.s.x.array.size)
    forms = {"consistent (ufl.derivative)": ufl.derivative(F, w, dw),
             "primal-dual: derivative + correction": ufl.derivative(F, w, dw)
             + ds.jacobian_correction(v, dv, wt, space.dx),
             "primal-dual: tangent written out (default)": ds.tangent_form(v, dv, wt, space.dx)
             + mat.incompressibility_ufl(dv, dp, wt, q, space.dx)}
    print("\n| Jacobian | ms (µs/cell) |\n|---|---|")
    mats = {}
    for name, J in forms.items():
        af = compat.form(J, jit_params=compat.jit_params())
        A = dolfinx.fem.petsc.create_matrix(af)
        tj = _best_matrix_time(A, af, best)
        mats[name] = A
        print(f"| {name} | {tj * 1e3:.1f} ({tj / ncell * 1e6:.1f}) |")
    a, b = (mats[k] for k in list(forms)[1:])
    d = a.copy()
    d.axpy(-1.0, b)
    print(f"primal-dual Jacobians, the two ways: ‖ΔA‖/‖A‖ = {d.norm() / a.norm():.1e}")
    for A in list(mats.values()) + [d]:
        A.destroy()


def quadrature_figures(msh, mat, ncell: int, best: int, degrees=(6, 5, 4)):
    """The default Jacobian (primal–dual, written out) and the residual per cell at each MINI
    quadrature degree (fxcontact's flags, random velocity and dual stress); the degrees are
    timed in turn, ``best`` rounds, the fastest of each kept."""
    import basix

    from fxcontact.element.dual import DualStress
    forms = {}
    for deg in degrees:
        space = fx.MixedSpace(msh, quadrature_degree=deg)
        w = dolfinx.fem.Function(space.W)
        w.x.array[:] = np.random.default_rng(1).normal(size=w.x.array.size)
        v, p = ufl.split(w)
        wt, q = ufl.TestFunctions(space.W)
        dv, dp = ufl.split(ufl.TrialFunction(space.W))
        ds = DualStress(mat, space.W, deg)
        ds.s.x.array[:] = np.random.default_rng(2).normal(size=ds.s.x.array.size)
        J = ds.tangent_form(v, dv, wt, space.dx) + mat.incompressibility_ufl(dv, dp, wt, q,
                                                                             space.dx)
        F = mat.residual(v, p, wt, q, space.dx, 1.0)
        af = compat.form(J, jit_params=compat.jit_params())
        Lf = compat.form(F, jit_params=compat.jit_params())
        forms[deg] = (af, Lf, dolfinx.fem.petsc.create_matrix(af),
                      dolfinx.fem.petsc.create_vector(Lf), (w, ds))
    tj = {deg: np.inf for deg in degrees}
    tf = dict(tj)
    for _ in range(best):
        for deg, (af, Lf, A, b, _keep) in forms.items():
            tj[deg] = min(tj[deg], _best_matrix_time(A, af, 1))
            t0 = time.perf_counter()
            with b.localForm() as bl:
                bl.set(0.0)
            dolfinx.fem.petsc.assemble_vector(b, Lf)
            tf[deg] = min(tf[deg], time.perf_counter() - t0)
    print("\n| MINI quadrature degree | points per tetrahedron | Jacobian ms (µs/cell) | "
          "residual ms (µs/cell) |\n|---|---|---|---|")
    for deg in degrees:
        nq = len(basix.make_quadrature(basix.CellType.tetrahedron, deg)[1])
        print(f"| {deg} | {nq} | {tj[deg] * 1e3:.1f} ({tj[deg] / ncell * 1e6:.1f}) | "
              f"{tf[deg] * 1e3:.1f} ({tf[deg] / ncell * 1e6:.2f}) |")
    for af, Lf, A, b, _keep in forms.values():
        A.destroy()
        b.destroy()


class _Recorder:
    """Collects the SolveInfo of every accepted increment and the callback times."""

    def __init__(self):
        self.infos, self.callbacks, self.sims = [], [], []
        self._orig = fxsim.Simulation.step
        rec = self

        def step(sim, *args, **kw):
            if not rec.sims or rec.sims[-1] is not sim:
                rec.sims.append(sim)
            c0 = dict(sim.solver.callback_times) if getattr(sim, "solver", None) else None
            res = rec._orig(sim, *args, **kw)
            c1 = dict(sim.solver.callback_times)
            rec.infos.append(res.info)
            rec.callbacks.append({k: c1[k] - (c0 or {}).get(k, 0.0) for k in c1})
            return res

        fxsim.Simulation.step = step

    def restore(self):
        fxsim.Simulation.step = self._orig


def newton_run(size: float, t_end: float, flags: bool, skip_lift: bool):
    """One drawing run with the switches; returns the per-iteration figures."""
    saved = (list(compat.JIT_EXTRA_COMPILE_ARGS), fxpetsc.NonlinearProblem.skip_zero_lifting)
    compat.JIT_EXTRA_COMPILE_ARGS[:] = saved[0] if flags else []
    fxpetsc.NonlinearProblem.skip_zero_lifting = skip_lift
    rec = _Recorder()
    try:
        res = run_drawing(DrawingCase(size=size, t_end=t_end), pictures=False)
    finally:
        rec.restore()
        compat.JIT_EXTRA_COMPILE_ARGS[:] = saved[0]
        fxpetsc.NonlinearProblem.skip_zero_lifting = saved[1]
    if res.status != "completed":
        raise RuntimeError(f"the run failed: {res.message}")
    sim = rec.sims[-1]
    infos, cbs = rec.infos[1:], rec.callbacks[1:]     # first increment: compilation
    its = sum(i.iterations for i in infos)
    tot = lambda k: sum(i.times.get(k, 0.0) for i in infos)  # noqa: E731
    ev = lambda k: sum(i.evaluations.get(k, 0) for i in infos)  # noqa: E731
    cb = sum(sum(c.values()) for c in cbs)
    out = dict(its=its, iterations=[i.iterations for i in rec.infos],
               F_per_it=ev("residual") / its, J_per_it=ev("jacobian") / its,
               res_asm=tot("assembly_residual") / its, jac_asm=tot("assembly_jacobian") / its,
               res_asm_per_eval=tot("assembly_residual") / ev("residual"),
               contact=tot("contact") / its,
               python=(cb - tot("assembly") - tot("contact")) / its,
               linear=tot("linear_solve") / its, other=tot("other") / its,
               total=tot("total") / its, dofs=res.dofs,
               force=np.array([r["drawing_force"] for r in res.history]),
               v=sim.w.x.array.copy(), liftings=dict(sim.problem.liftings))
    return out


def newton_figures(size: float, t_end: float, repeat: int):
    print(f"\n## Newton: wire drawing --size {size} --t_end {t_end}, 1 process, first increment "
          f"not timed; ms per Newton iteration (best of {repeat})")
    best = {}
    for _ in range(repeat):
        for name, sw in VARIANTS:
            r = newton_run(size, t_end, **sw)
            if name not in best or r["total"] < best[name]["total"]:
                best[name] = r
    ref = best["before"]
    print(f"dofs {ref['dofs']}, Newton iterations per increment {ref['iterations']}")
    print("| variant | F/it | J/it | residual asm | (per F) | Jacobian asm | contact | python "
          "| linear | other | total | Δforce | max \\|Δv\\|/max \\|v\\| "
          "| liftings done/skipped |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    ms = lambda x: f"{x * 1e3:.1f}"  # noqa: E731
    for name, _ in VARIANTS:
        r = best[name]
        same_its = r["iterations"] == ref["iterations"]
        df = np.max(np.abs(r["force"] - ref["force"]) / np.abs(ref["force"])) \
            if same_its and len(r["force"]) == len(ref["force"]) else np.nan
        dv = np.max(np.abs(r["v"] - ref["v"])) / np.max(np.abs(ref["v"])) if same_its else np.nan
        print(f"| {name} | {r['F_per_it']:.2f} | {r['J_per_it']:.2f} | {ms(r['res_asm'])} | "
              f"{ms(r['res_asm_per_eval'])} | {ms(r['jac_asm'])} | {ms(r['contact'])} | "
              f"{ms(r['python'])} | {ms(r['linear'])} | {ms(r['other'])} | {ms(r['total'])} | "
              f"{df:.1e} | {dv:.1e} | {r['liftings']['done']}/{r['liftings']['skipped']} |")
        if not same_its:
            print(f"  ({name}: Newton iterations {r['iterations']} differ from before)")
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=float, default=0.4, help="demo size (0.4: 12.4k dofs)")
    ap.add_argument("--t_end", type=float, default=0.01, help="process time of the Newton runs")
    ap.add_argument("--repeat", type=int, default=1, help="runs per variant (the fastest kept)")
    ap.add_argument("--best", type=int, default=5, help="kernel timings: best of")
    ap.add_argument("--skip-newton", action="store_true", help="the kernel figures only")
    ap.add_argument("--skip-kernel", action="store_true", help="the Newton figures only")
    args = ap.parse_args(argv)
    if MPI.COMM_WORLD.size != 1:
        ap.error("run on 1 process")
    if not args.skip_kernel:
        kernel_figures(args.size, args.best)
    if not args.skip_newton:
        newton_figures(args.size, args.t_end, args.repeat)


if __name__ == "__main__":
    main()
