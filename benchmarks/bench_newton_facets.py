"""Newton iterations per increment: analytic cylinder, flat facets and Nagata patches.

Usage::

    python benchmarks/bench_newton_facets.py                      # every case (a few minutes)
    python benchmarks/bench_newton_facets.py --quick              # first two cases (smoke check)
    python benchmarks/bench_newton_facets.py --cases baseline deep soft-penalty
    python benchmarks/bench_newton_facets.py --list               # case names and overrides
    mpirun -n 2 python benchmarks/bench_newton_facets.py --quick  # same rows, ranks = 2

Problem: the cylinder ironing of ``fxcontact.processes.ironing`` (rigid cylinder R = 5 mm
pressed by δ into an elastic slab one element thick, then translated along x; frictionless nodal
penalty contact, Newton with full steps, rtol 1e-9 on the residual for every tool). Every case
is a set of overrides on top of the reduced configuration ``ironing.QUICK`` (see ``CASES``) and
runs three variants with the same scheme (``implicit`` unless the case says otherwise): the analytic
cylinder, the flat-faceted coarse tool (1.7 mm facets, Forge's closest-facet plane) and the same
coarse facets smoothed by Nagata patches. The question is whether Nagata smoothing reduces the
Newton iterations compared to the flat facets.

Per variant the table gives, over the steady translation phase (every accepted increment after
the indentation and the first ``settle`` = 2 steps of travel): the Newton iterations per
accepted increment (mean / max / std), the cut-backs of the whole run, the mean vertical tool
force F_z, its oscillation ((max − min)/(2 mean) after removing the linear trend), the mean
number of contact nodes, and the wall time (max over ranks). A verdict line per case then
states whether the Nagata tool needs fewer iterations than the flat one (mean) and no more at
worst (max).

Reading hints:

* The tolerance is the same for all tools, so the counts compare convergence rates. The flat
  tool's gap is piecewise linear in the nodal positions: as long as no node changes facet (or
  enters or leaves contact) the Gauss–Newton tangent is exact and Newton converges in one or
  two iterations. The curved tools (analytic, Nagata) have a curved gap, whose Gauss–Newton
  tangent (``implicit``) or exact Hessian (``implicit-exact``) still leaves several iterations
  down to 1e-9; fewer iterations with flat facets do not mean a better answer (compare F_z and
  the oscillation with the analytic tool).
* ``start_offset 0`` puts a node exactly under the bottom vertex row of the faceted tools at
  t = 0 (a tie between two facets); ``step=h`` moves the tool one element per increment, so
  the tie recurs at every increment.
* ``thesis size`` has only 3 steady increments: its statistics are coarse.
* A failed variant (an increment that did not converge after the cut-backs) keeps its status;
  its statistics are NaN if fewer than 3 steady increments were accepted.

The ``groove`` cases run ``fxcontact.processes.groove`` instead (a concave tool: a round bar
in a turning groove of 36 to 180 facets, against the analytic bore; statistics over the
rotation).
The ``fine tools`` cases compare the fine (0.2 mm) flat and Nagata ironing tools.

Rows are upserted by (ranks, case, variant) into ``benchmarks/results/newton_facets.csv`` with
the case's overrides and the resolved parameters.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import re
import time
from typing import List, NamedTuple

from _common import read_csv
from mpi4py import MPI

from fxcontact.processes import groove, ironing

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, "results")


def tools(scheme: str = "implicit") -> tuple:
    """The three compared variants (analytic, flat coarse, Nagata coarse) under ``scheme``."""
    return (("analytic", None, scheme), ("flat", "coarse", scheme), ("nagata", "coarse", scheme))


def fine_tools(scheme: str = "implicit") -> tuple:
    """The analytic tool and the fine (0.2 mm) flat and Nagata tools under ``scheme``."""
    return (("analytic", None, scheme), ("flat", "fine", scheme), ("nagata", "fine", scheme))


class Case(NamedTuple):
    name: str
    params: dict  # overrides of the study's QUICK (``variants`` defaults to tools("implicit"))
    demo: str = "ironing"  # "ironing" (fxcontact.processes.ironing) or "groove" (.groove)


#: The sweep, in order (``--quick`` runs the first two). Add cases here.
CASES: List[Case] = [
    Case("baseline", {}),
    Case("step=h, node under vertex", dict(step=0.25, start_offset=0.0, travel=2.0)),
    Case("start_offset 0", dict(start_offset=0.0)),
    Case("deep", dict(indentation=0.15, travel=1.2)),
    Case("soft penalty", dict(beta=10.0)),
    Case("implicit-exact", dict(variants=tools("implicit-exact"))),
    Case("unstructured tool", dict(tool_mesh="gmsh")),
    Case("thesis size", dict(h_fine=1.0, indentation=0.15, step=1.0, travel=5.0, margin=6.0,
                             margin_fine=1.0, fine_depth=2.0, h_coarse=2.0, start_offset=0.0)),
    Case("fine tools", dict(variants=fine_tools("implicit"))),
    Case("fine tools, start_offset 0", dict(start_offset=0.0, variants=fine_tools("implicit"))),
    # concave tool: round bar in a turning groove (processes.groove), 36 to 180 facets
    Case("groove, 36 facets", {}, demo="groove"),
    Case("groove, 72 facets", dict(coarse_facets=72), demo="groove"),
    Case("groove, 180 facets", dict(coarse_facets=180), demo="groove"),
]

#: Parameters of ``ironing.run`` (and ``groove.run``) written to the CSV (resolved values).
PARAMS = ["h_fine", "indentation", "n_indent", "step", "travel", "settle", "start_offset",
          "beta", "tool_mesh", "phase", "margin", "margin_fine", "fine_depth", "h_coarse",
          "growth", "line_search", "h", "coarse_facets", "rotation_step", "n_rotation"]
STATS = ["status", "newton_mean", "newton_max", "newton_std", "newton_total", "cutbacks",
         "force_mean", "oscillation", "contact_nodes_mean", "penetration_max", "fallbacks",
         "wall_time"]
FIELDS = ["ranks", "case", "variant", "overrides"] + STATS + PARAMS


def slug(name: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")


def describe(params: dict) -> str:
    """Compact text of a case's overrides (variants by their scheme)."""
    items = []
    for k, v in params.items():
        if k == "variants":
            v = "/".join(sorted({s for _, _, s in v}))
        items.append(f"{k}={v}")
    return " ".join(items) if items else "-"


def case_rows(comm, name: str, run, kw: dict, overrides: str) -> List[dict]:
    """Run one case; one CSV/table row per variant (a single error row if run() raised)."""
    t0 = time.perf_counter()
    try:
        res = run(**kw, output_dir=None, progress=False, picture=False, comm=comm)
    except Exception as e:  # e.g. run()'s parameter validation, raised on every rank
        wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        return [{"ranks": comm.size, "case": name, "variant": "-", "overrides": overrides,
                 "status": f"error: {type(e).__name__}: {e}", "wall_time": wall}]
    par = res.get("parameters", {}) or {}
    rows = []
    for s in res["summary"]:
        row = {"ranks": comm.size, "case": name, "variant": s["variant"],
               "overrides": overrides}
        row.update({k: s.get(k, float("nan")) for k in STATS})
        row.update({k: par.get(k, kw.get(k, "")) for k in PARAMS})
        rows.append(row)
    return rows


# ------------------------------------------------------------------------------ CSV / tables
def key(r) -> tuple:
    return (str(r["ranks"]), r["case"], r["variant"])


def upsert_csv(path: str, rows: List[dict]):
    """Replace the rows of the same (ranks, case) and append the new ones."""
    done = {(str(r["ranks"]), r["case"]) for r in rows}
    kept = [r for r in read_csv(path) if key(r)[:2] not in done]
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(kept + rows)


def _num(r, k, fmt, width):
    v = r.get(k, float("nan"))
    try:
        v = float(v)
    except (TypeError, ValueError):
        return f"{'-':>{width}s}"
    return f"{'-':>{width}s}" if math.isnan(v) else f"{v:>{width}{fmt}}"


NUMS = [("newton_mean", ".2f", 7, "NR avg"), ("newton_max", ".0f", 6, "NR max"),
        ("newton_std", ".2f", 6, "NR std"), ("cutbacks", ".0f", 4, "cut"),
        ("force_mean", ".1f", 9, "Fz [N]"), ("oscillation", ".2%", 8, "osc"),
        ("contact_nodes_mean", ".1f", 6, "nodes"), ("wall_time", ".1f", 7, "wall s")]


def print_table(rows: List[dict]):
    wc = max([len("case")] + [len(r["case"]) for r in rows])
    wv = max([len("variant")] + [len(r["variant"]) for r in rows])
    ws = max([len("status")] + [len(r["status"]) for r in rows if len(r["status"]) <= 24])
    head = (f"{'case':<{wc}s} {'variant':<{wv}s} {'status':<{ws}s}"
            + "".join(f" {lab:>{w}s}" for _, _, w, lab in NUMS))
    print(head)
    print("-" * len(head))
    prev = None
    for r in rows:
        if prev is not None and r["case"] != prev:
            print()
        prev = r["case"]
        line = f"{r['case']:<{wc}s} {r['variant']:<{wv}s} {r['status']:<{ws}s}"
        if r["status"].startswith("error"):
            print(line)
            continue
        print(line + "".join(" " + _num(r, k, fmt, w) for k, fmt, w, _ in NUMS))


def verdict(case: str, rows: List[dict]) -> List[str]:
    """Per Nagata variant of a case, the facts against the flat variant of the same name."""
    by = {r["variant"]: r for r in rows}
    out = []
    for name, nag in by.items():
        if not name.startswith("nagata"):
            continue
        flat = by.get("flat" + name[len("nagata"):])
        if flat is None:
            continue
        # the analytic variant of the same scheme: "analytic-implicit" for "nagata-coarse-implicit"
        ana = max((r for v, r in by.items() if v.startswith("analytic")
                   and name.endswith(v[len("analytic"):])),
                  key=lambda r: len(r["variant"]), default=None)
        nm, nx = float(nag["newton_mean"]), float(nag["newton_max"])
        fm, fx = float(flat["newton_mean"]), float(flat["newton_max"])
        if any(math.isnan(v) for v in (nm, nx, fm, fx)):
            if nag["status"] == "ok" and flat["status"] != "ok" and not math.isnan(nm):
                out.append(f"{case}: flat facets {flat['status']} (Newton did not converge "
                           f"even after the cut-backs), Nagata converged with {nm:.2f} / "
                           f"{nx:.0f} iterations")
            else:
                out.append(f"{case}: {name} vs {flat['variant']}: not comparable (status "
                           f"{nag['status']!r} / {flat['status']!r})")
            continue
        tail = ""
        if ana is not None and not math.isnan(float(ana["newton_mean"])):
            tail = (f"; {ana['variant']} {float(ana['newton_mean']):.2f} / "
                    f"{float(ana['newton_max']):.0f}")
        out.append(f"{case}: Nagata mean {nm:.2f} < flat mean {fm:.2f}: "
                   f"{'yes' if nm < fm else 'no'}; Nagata max {nx:.0f} <= flat max {fx:.0f}: "
                   f"{'yes' if nx <= fx else 'no'}{tail}")
    return out or [f"{case}: no Nagata/flat pair to compare"]


# ------------------------------------------------------------------------------ main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="+", default=None, metavar="NAME",
                    help="cases to run, by name or slug (e.g. 'soft penalty' or soft-penalty); "
                         "default: all")
    ap.add_argument("--quick", action="store_true", help="only the first two cases")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--csv", default=os.path.join(RESULTS, "newton_facets.csv"))
    a = ap.parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *x, **k: None)
    names = [c.name for c in CASES]
    if a.list:
        for c in CASES:
            say(f"{c.name!r:32s} {slug(c.name):28s} {c.demo}: {describe(c.params)}")
        return None
    if a.cases is not None:
        lookup = {n: n for n in names} | {slug(n): n for n in names}
        bad = [c for c in a.cases if c not in lookup]
        if bad:
            ap.error(f"unknown case(s) {bad}; known: {names}")
        selected = {lookup[c] for c in a.cases}
    else:
        selected = set(names[:2] if a.quick else names)

    demos = {"ironing": ironing, "groove": groove}
    t_all = time.perf_counter()
    rows: List[dict] = []
    for c in CASES:
        if c.name not in selected:
            continue
        demo = demos[c.demo]
        kw = {**demo.QUICK, "variants": tools("implicit"), **c.params}
        say(f"[{c.name}] {c.demo}: {describe(c.params)} ...", flush=True)
        new = case_rows(comm, c.name, demo.run, kw, describe(c.params))
        rows += new
        if comm.rank == 0:
            upsert_csv(a.csv, new)
    wall = comm.allreduce(time.perf_counter() - t_all, op=MPI.MAX)

    if comm.rank == 0 and rows:
        print(f"\nNewton iterations per accepted increment over the steady phase (translation "
              f"or rotation), "
              f"rtol 1e-9 for every tool; {comm.size} rank(s)")
        print_table(rows)
        print()
        for c in dict.fromkeys(r["case"] for r in rows):
            crow = [r for r in rows if r["case"] == c]
            errors = [r["status"] for r in crow if r["status"].startswith("error")]
            for line in ([f"{c}: {e}" for e in errors] or verdict(c, crow)):
                print(line)
        print(f"\ntotal wall time {wall:.1f} s; CSV -> {a.csv}")
    return rows


if __name__ == "__main__":
    main()
