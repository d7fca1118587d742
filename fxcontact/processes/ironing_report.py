"""Statistics, tables and pictures of the tool-comparison studies (:mod:`~fxcontact.processes.
ironing`, :mod:`~fxcontact.processes.groove`): one summary row per variant, the ``summary.csv``,
a text table and the PNGs of the tool force, the Newton iterations and the contact nodes versus
time.

**Force oscillation** (:func:`oscillation`): over the steady phase the least-squares linear
trend of F_z(t) is removed (a finite block, a slowly changing state) and ``oscillation =
(max − min)/(2·|mean|)`` of the detrended force, the same definition for every variant
(``oscillation_std``: std/|mean| of the detrended force). Newton statistics (mean, max, std of
the iterations per increment) are taken over the same increments; the shares of the Newton time
(contact terms, UFL assembly, linear solves, other: history columns ``wall_*``) over the whole
run.

The pictures are drawn on rank 0 (matplotlib); the rest is plain arithmetic on the histories,
the same on every rank.
"""

from __future__ import annotations

import csv
import os

import numpy as np

from fxcontact.io.series import pyplot

__all__ = ["oscillation", "summarize", "collect", "write_summary", "plot_all", "TABLE",
           "format_table", "report"]


def oscillation(t: np.ndarray, f: np.ndarray) -> tuple:
    """``((max − min)/(2 |mean|), std/|mean|)`` of ``f`` after removing its least-squares line
    in ``t`` (dimensionless; NaN for fewer than 3 values)."""
    if len(f) < 3:
        return float("nan"), float("nan")
    A = np.c_[np.ones_like(t), t - t.mean()]
    coef, *_ = np.linalg.lstsq(A, f, rcond=None)
    r = f - A @ coef
    m = abs(float(np.mean(f)))
    return float((r.max() - r.min()) / (2.0 * m)), float(np.std(r) / m)


def summarize(res: dict, first: int) -> dict:
    """Summary row of a variant (a result of :func:`~fxcontact.processes.ironing.run_stages`):
    statistics over the increments ``first:`` (steady phase; NaN if a failed variant has fewer
    than 3 of them), time shares over the whole run.

    Returns:
        dict: ``variant``, ``status``, ``newton_mean``/``_max``/``_std`` (iterations per
        increment), ``newton_total``, ``cutbacks``, ``force_mean`` (mean F_z [N]),
        ``oscillation``, ``oscillation_std``, ``contact_nodes_mean``, ``penetration_max``
        (true, [mm]), ``fallbacks`` (Nagata), ``wall_time`` and ``newton_time`` [s],
        ``time_per_iteration`` [s], ``contact_share``, ``assembly_share``, ``linear_share``,
        ``other_share`` (of the Newton time), ``tool_bottom_gap``, ``tool_dev_out``,
        ``tool_dev_in`` [mm] (of :func:`~fxcontact.processes.ironing.tool_deviation`).
    """
    h = res["history"]
    nan = float("nan")

    def col(k):
        return np.array([row.get(k, nan) for row in h], dtype=float)

    t, fz, nits = col("time"), col("tool_force_z"), col("newton_iterations")
    s = slice(first, None)
    steady = len(h) - first >= 3

    def stat(f, a):
        return float(f(a[s])) if steady else nan

    osc, osc_std = oscillation(t[s], fz[s]) if steady else (nan, nan)
    tot = float(np.sum(col("wall_total")))
    share = {k: float(np.sum(col(f"wall_{k}")) / tot) if tot > 0 else nan
             for k in ("contact", "assembly", "linear_solve", "other")}
    return {"variant": res["name"], "status": res["status"],
            "newton_mean": stat(np.mean, nits), "newton_max": stat(np.max, nits),
            "newton_std": stat(np.std, nits), "newton_total": float(np.sum(nits)),
            "cutbacks": float(np.sum(col("cutbacks"))), "force_mean": stat(np.mean, fz),
            "oscillation": osc, "oscillation_std": osc_std,
            "contact_nodes_mean": stat(np.mean, col("contact_nodes")),
            "penetration_max": float(np.max(col("contact_penetration_true"))) if h else nan,
            "fallbacks": float(np.sum(col("contact_fallbacks"))),
            "wall_time": res["wall_time"], "newton_time": tot,
            "time_per_iteration": tot / max(float(np.sum(nits)), 1.0),
            "contact_share": share["contact"], "assembly_share": share["assembly"],
            "linear_share": share["linear_solve"], "other_share": share["other"],
            "tool_bottom_gap": res["deviation"]["bottom_gap"],
            "tool_dev_out": res["deviation"]["dev_out"],
            "tool_dev_in": res["deviation"]["dev_in"]}


def collect(results: list, first: int, common: dict, settle, variants, output_dir) -> dict:
    """The dict a study's ``run`` returns, from the variants' results: the rows of
    :func:`summarize` from increment ``first`` (``summary``, and ``by_name``), ``results`` by
    name, ``parameters`` (``common`` without the communicator, with ``settle`` and
    ``variants``); ``summary.csv`` written by rank 0 into ``output_dir`` (unless None) and its
    path in ``summary_csv``; ``png`` left empty for the caller."""
    summary = [summarize(r, first) for r in results]
    out = {"summary": summary, "by_name": {row["variant"]: row for row in summary},
           "results": {r["name"]: r for r in results},
           "parameters": {**{k: v for k, v in common.items() if k != "comm"},
                          "settle": settle, "variants": list(variants)},
           "png": {}, "summary_csv": None}
    if output_dir is not None and common["comm"].rank == 0:
        out["summary_csv"] = write_summary(summary, os.path.join(output_dir, "summary.csv"))
    return out


def write_summary(summary: list, path: str) -> str:
    """Write the rows of :func:`summarize` as a CSV file (call on one rank). Returns ``path``."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(summary[0].keys()))
        w.writeheader()
        w.writerows(summary)
    return path


def plot_all(results: list, output_dir: str, n_indent: int,
             xlabel: str = "time [s] (indentation, then translation)") -> dict:
    """PNGs of the vertical tool force F_z [N], the Newton iterations and the contact nodes
    versus time, one panel per contact scheme, one curve per variant (analytic wide and pale,
    fine tools dotted; a cross where a failed variant stopped; a grey line at the end of the
    ``n_indent`` first increments). Call on one rank.

    Returns:
        dict of the paths by ``"force"``, ``"newton"``, ``"contact_nodes"``.
    """
    plt = pyplot()

    colors = {"analytic": "k", "flat": "C3", "nagata": "C0"}
    schemes = [s for s in ("explicit", "quasi-implicit", "implicit", "implicit-exact")
               if any(r["scheme"] == s for r in results)]
    out = {}
    for key, ylabel, fname in (("tool_force_z", "vertical tool force $F_z$ [N]", "force"),
                               ("newton_iterations", "Newton iterations", "newton"),
                               ("contact_nodes", "contact nodes", "contact_nodes")):
        fig, axes = plt.subplots(1, len(schemes), figsize=(6 * len(schemes), 4.5),
                                 sharey=True, squeeze=False)
        for ax, scheme in zip(axes[0], schemes):
            for r in results:
                if r["scheme"] != scheme:
                    continue
                t = np.array([row["time"] for row in r["history"]])
                y = np.array([row[key] for row in r["history"]], dtype=float)
                fine = r["facets"] == "fine"
                wide = r["tool"] == "analytic"  # under the curves that coincide with it
                ax.plot(t, y, color=colors[r["tool"]], ls=":" if fine else "-",
                        lw=4.0 if wide else (1.0 if fine else 1.5), alpha=0.35 if wide else 1.0,
                        marker="o" if key != "tool_force_z" and not wide else None,
                        ms=2.5, label=r["name"] + ("" if r["status"] == "ok"
                                                   else f" ({r['status']})"),
                        zorder=1 if wide else 2)
                if r["status"] != "ok" and len(t):  # mark where a failed variant stopped
                    ax.plot(t[-1:], y[-1:], "X", color=colors[r["tool"]], ms=10, zorder=3)
            ax.axvline(n_indent, color="0.6", lw=0.8)
            ax.set_title(f"{scheme} scheme")
            ax.set_xlabel(xlabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        axes[0][0].set_ylabel(ylabel)
        fig.tight_layout()
        path = os.path.join(output_dir, f"{fname}.png")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        out[fname] = path
    return out


#: Columns of :func:`format_table`: (key of the summary row, format, heading).
TABLE = [("variant", "{:<24s}", "variant"), ("newton_mean", "{:>7.2f}", "NR avg"),
         ("newton_max", "{:>7.0f}", "NR max"), ("newton_std", "{:>7.2f}", "NR std"),
         ("cutbacks", "{:>4.0f}", "cut"), ("force_mean", "{:>9.1f}", "Fz [N]"),
         ("oscillation", "{:>7.2%}", "osc"), ("contact_nodes_mean", "{:>6.1f}", "nodes"),
         ("penetration_max", "{:>9.2e}", "pen [mm]"), ("fallbacks", "{:>4.0f}", "fb"),
         ("wall_time", "{:>7.1f}", "wall s"), ("time_per_iteration", "{:>7.3f}", "s/it"),
         ("contact_share", "{:>8.1%}", "contact"), ("assembly_share", "{:>7.1%}", "asm"),
         ("linear_share", "{:>7.1%}", "solve")]


def format_table(summary: list) -> str:
    """Text table of the rows of :func:`summarize` (columns :data:`TABLE`), a heading line
    first."""
    def width(fmt):
        return int("".join(ch for ch in fmt.split(":")[1] if ch.isdigit() or ch == ".")
                   .split(".")[0])
    head = "".join(f"{lab:<{width(fmt)}s}" if k == "variant" else f"{lab:>{width(fmt)}s}"
                   for k, fmt, lab in TABLE)
    return "\n".join([head] + ["".join(fmt.format(row[k]) for k, fmt, _ in TABLE)
                               for row in summary])


def report(res: dict, body: str, what: str) -> str:
    """Text report of a study's result ``res``: the mesh of the first variant, the table of
    :func:`format_table` and the outputs (``body``: the workpiece, ``what``: the nodes and the
    phase of the statistics)."""
    r0 = next(iter(res["results"].values()))
    return "\n".join([f"{body}: {r0['cells']} tetrahedra, {r0['dofs']} dofs, "
                      f"{r0['surface_nodes']} {what}", format_table(res["summary"]),
                      f"outputs: {res['summary_csv']}, {', '.join(res['png'].values())}"])
