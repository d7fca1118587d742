"""Pieces shared by the forming processes: nodal gathers, the numerics columns of a history
row and their summary, steady values over a window, a meridian (symmetry-face) section of cell
fields, curve and section pictures, the CSV of the rows; a case's flow-stress material and heat
(their checks, the theory's mean flow stress, the report's lines).

Every function that communicates is collective (call it on every rank); the pictures are drawn
on rank 0 only (matplotlib, no VTK).
"""

from __future__ import annotations

import csv
import functools
import math
import os
import types
import warnings
from dataclasses import dataclass, field
from typing import Callable, Dict, Optional, Sequence

import numpy as np
from mpi4py import MPI

from fxcontact import compat
from fxcontact.collective import together
from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.io.outputs import output_dir_problem
from fxcontact.io.series import pyplot
from fxcontact.materials import Viscoplastic
from fxcontact.processes.contact_laws import ContactLaws
from fxcontact.processes.monitor import contact_lines
from fxcontact.simulation import (IncrementError, format_iteration_split, format_wall_split,
                                  wall_split)
from fxcontact.steady import steady_window
from fxcontact.thermal import HeatSetup

__all__ = ["CaseBase", "script_main", "gather", "numerics_columns", "run_summary",
           "steady_values", "run_increments", "ProcessResult", "meridian_section",
           "vertex_field", "plot_sections", "plot_curves", "write_rows", "mean_norton_hoff",
           "check_output_dir",
           "check_material_heat", "theory_temperature", "material_text", "heat_columns",
           "heat_lines"]


class _ClassOrCase:
    """A method called on the class or on a case: its first argument is then the class's
    default case or the case itself."""

    def __init__(self, func):
        self.func = func
        functools.update_wrapper(self, func)

    def __get__(self, case, cls):
        return types.MethodType(self.func, cls() if case is None else case)


class CaseBase(ContactLaws):
    """What the process cases (frozen dataclasses) share: :meth:`quick` (the reduced size of
    the tests, the class's ``QUICK`` fields), :meth:`replace`, the ``penalty`` and
    ``friction`` fields with their former spellings
    (:class:`~fxcontact.processes.contact_laws.ContactLaws`) and the checks of their common
    fields, each a ``ValueError`` naming the field."""

    QUICK: Dict[str, object] = {}

    @_ClassOrCase
    def quick(self, **changes):
        """The reduced case of the tests: the ``QUICK`` fields replaced, then ``changes``.
        On the class (``ExtrusionCase.quick(alpha=30.0)``) from the default case; on a case
        (``case.quick()``, as the rolling cases) from that case: its other fields are kept."""
        return self.replace(**{**self.QUICK, **changes})

    def check_positive(self, names):
        """ValueError naming the first of the fields ``names`` that is not a finite number
        > 0."""
        for key in names:
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{key} must be a finite number > 0, got {v!r}")

    def check_remesh_fields(self):
        """``remesh_min_quality`` in (0, 1) and ``remesh_zone_h`` None or > 0."""
        q = self.remesh_min_quality
        if not (isinstance(q, (int, float)) and 0 < q < 1):
            raise ValueError(f"remesh_min_quality must be in (0, 1), got {q!r}")
        if self.remesh_zone_h is not None:
            self.check_positive(("remesh_zone_h",))

    def check_increment(self, speed: float, element: float, what: str):
        """The increment against the mesh: ``dt`` moving the fastest material (``speed``
        [mm/s], ``what`` it is) by more than the workpiece's ``length`` is refused; by more than
        one ``element`` [mm], a warning — the contact then follows a node across several
        elements in one increment. Both say the dt that keeps one element per increment."""
        travel, dt_one = speed * self.dt, element / speed
        if travel >= self.length:
            raise ValueError(f"dt = {self.dt:g} s moves {what} by {travel:.3g} mm in one "
                             f"increment, more than the workpiece's length {self.length:g} mm: "
                             f"take dt <= {dt_one:.3g} s (one element of {element:.3g} mm per "
                             f"increment)")
        if travel > element * (1.0 + 1e-9):
            warnings.warn(f"dt = {self.dt:g} s moves {what} by {travel:.3g} mm per increment = "
                          f"{travel / element:.2g} elements of {element:.3g} mm: the contact "
                          f"follows a node across several elements at once (coarse in time); "
                          f"dt <= {dt_one:.3g} s keeps one element per increment",
                          UserWarning, stacklevel=4)

    def check_bar_and_die(self, alpha_max: float):
        """R1 < R0, the die semi-angle alpha in (0, alpha_max) degrees, the nose ratio in
        (0, 1), the Norton–Hoff m in (0, 1]."""
        if not self.R1 < self.R0:
            raise ValueError(f"R1 ({self.R1}) must be smaller than R0 ({self.R0})")
        if not 0 < self.alpha < alpha_max:
            raise ValueError(f"alpha (die semi-angle, degrees) must be in (0, {alpha_max:g}), "
                             f"got {self.alpha}")
        if not 0 < self.nose_ratio < 1:
            raise ValueError(f"nose_ratio must be in (0, 1), got {self.nose_ratio}")
        if not 0 < self.m <= 1:
            raise ValueError(f"m must be in (0, 1], got {self.m}")


def script_main(parser, case_type, run, default=None, argv=None, output_dir="results"):
    """The command line of a process script: ``parser`` with the script's own options (each
    named after a field of ``case_type``) gets ``--quick`` (the case's :meth:`quick`),
    ``--vtk_every``, ``--no-pictures``, ``--output-dir`` and ``--verbose``/``--quiet``; the
    case is ``default`` (or the quick one) with the fields given; ``run(case, ...)`` is run and
    its ``report()`` printed on rank 0. An option named after a former field (``--mu``,
    ``--beta``) sets the new field (:meth:`ContactLaws.with_options
    <fxcontact.processes.contact_laws.ContactLaws.with_options>`). Returns the result."""

    parser.add_argument("--quick", action="store_true", help="the reduced size of the tests")
    parser.add_argument("--vtk_every", type=int, default=0)
    parser.add_argument("--no-pictures", dest="pictures", action="store_false")
    parser.add_argument("--output-dir", dest="output_dir", default=output_dir)
    add_verbosity_arguments(parser)
    a = parser.parse_args(argv)
    configure_logging(verbose=a.verbose, quiet=a.quiet)
    changes = {k: v for k, v in vars(a).items()
               if k in case_type.__dataclass_fields__ and v is not None}
    base = case_type.quick() if a.quick else (default or case_type())
    res = run(base.with_options(**changes), output_dir=a.output_dir, pictures=a.pictures,
              vtk_every=a.vtk_every)
    if MPI.COMM_WORLD.rank == 0:
        print(res.report())
    return res


def gather(comm, arr) -> np.ndarray:
    """The ranks' arrays concatenated, on every rank (rank order)."""
    parts = comm.allgather(np.asarray(arr))
    return np.concatenate(parts) if parts else np.asarray(arr)


def numerics_columns(r: dict) -> Dict[str, float]:
    """The numerics of an increment from a :class:`~fxcontact.Simulation` history row: Newton
    iterations (all attempts, and of the converged one with its Krylov iterations), cut-backs,
    wall time split, volume change, smallest element quality, symmetry violation."""
    return dict(newton_iterations=r["newton_iterations_all"], cutbacks=r["cutbacks"],
                linear_iterations=r["linear_iterations"],
                newton_iterations_converged=r["newton_iterations"],
                wall=r["wall_increment_all"], wall_assembly=r["wall_assembly"],
                wall_linear_solve=r["wall_linear_solve"], wall_contact=r["wall_contact"],
                wall_factorisation=r.get("wall_factorisation", 0.0),
                volume_change=r["volume_change"], min_quality=r["min_quality"],
                symmetry_violation=r.get("symmetry_violation", 0.0))


def run_summary(rows: Sequence[dict]) -> dict:
    """Over the rows (with :func:`numerics_columns`): largest |volume change|, smallest
    quality, Newton mean and max, cut-backs, wall split."""
    return dict(max_volume_change=max(abs(q["volume_change"]) for q in rows),
                min_quality=min(q["min_quality"] for q in rows),
                newton_mean=float(np.mean([q["newton_iterations"] for q in rows])),
                newton_max=int(max(q["newton_iterations"] for q in rows)),
                cutbacks=int(sum(q["cutbacks"] for q in rows)),
                wall_split=wall_split(rows))


def run_increments(sim, dt: float, t_end: float, max_cutbacks: int, row: Callable,
                   steady_keys: Sequence[str], window: int, tol: float,
                   settled: Callable[[float], bool], stop_at_steady: bool = False,
                   progress: Optional[Callable[[dict], None]] = None):
    """Step ``sim`` to ``t_end`` by ``dt``; after each increment ``row(history_row)`` makes the
    process's row (collective) and ``progress(row)`` may log it. Once ``settled(t)``, the run
    is steady when the means of ``steady_keys`` over the last ``window`` increments and the
    window before agree within ``tol`` (:func:`fxcontact.steady.steady_window`); with
    ``stop_at_steady`` it stops there. An :class:`~fxcontact.IncrementError` ends the run
    (status "failed", its message kept).

    Returns ``(rows, status, message, steady)``, ``steady = (first, last)`` row indices of the
    steady window or None."""
    rows, steady = [], None
    status, message = "completed", ""
    while sim.t < t_end - 1e-9 * dt:
        try:
            res = sim.step(min(dt, t_end - sim.t), max_cutbacks=int(max_cutbacks))
        except IncrementError as err:   # MeshInversionError included
            status, message = "failed", str(err)
            break
        rows.append(row(res.row))
        if progress is not None:
            progress(rows[-1])
        if steady is None and settled(sim.t):
            first = steady_window(rows, steady_keys, window, tol)
            if first is not None:
                steady = (first, len(rows) - 1)
                if stop_at_steady:
                    break
    return rows, status, message, steady


@dataclass
class ProcessResult:
    """What every process run returns: status, the history (one dict per increment), the
    theory band, the size of the model and the numerics over the run; the steady window (row
    indices and times) and the power balance over it (else at the last increment); the
    outputs' paths. Each process adds its steady values."""

    status: str = "completed"
    message: str = ""
    history: list = field(default_factory=list)
    theory: dict = field(default_factory=dict)
    dofs: int = 0
    h: float = math.nan
    wall: float = math.nan
    time: float = 0.0
    ranks: int = 1
    increments: int = 0
    max_volume_change: float = math.nan
    min_quality: float = math.nan
    newton_mean: float = math.nan
    newton_max: int = 0
    cutbacks: int = 0
    wall_split: dict = field(default_factory=dict)
    steady_from: Optional[int] = None
    steady_to: Optional[int] = None
    steady_time: Optional[tuple] = None
    power_balance: Optional[float] = None
    #: the same with the penalty work: the discrete virtual-power identity (≈ round-off)
    power_balance_penalty: Optional[float] = None
    pictures: list = field(default_factory=list)
    csv: Optional[str] = None
    vtk: Optional[str] = None
    #: each contact's line of the run's summary (friction laws and their k, the penalty)
    contacts: list = field(default_factory=list)

    def report_text(self, lines) -> str:
        """The report's ``lines`` and the line of the pictures written (if any), joined."""
        pictures = getattr(self, "pictures", None)
        return "\n".join(list(lines) + (["pictures: " + ", ".join(pictures)] if pictures else []))

    def numerics_lines(self) -> list:
        """The report's lines on the power balance and the numerics."""

        return [f"power balance P_in / (D + P_f) - 1 = {100 * self.power_balance:.2f} % "
                f"(with the penalty work {self.power_balance_penalty:.1e})",
                f"Newton its mean {self.newton_mean:.1f} max {self.newton_max}, cut-backs "
                f"{self.cutbacks}; wall {self.wall:.0f} s: "
                f"{format_wall_split(self.wall_split)}",
                *[x for x in [format_iteration_split(self.wall_split)] if x],
                f"max |dV/V| {self.max_volume_change:.2e}; min element quality "
                f"{self.min_quality:.3f}", *self.contacts]


def finish_run(comm, sim, res, output_dir, name, pictures, vtk_every, draw):
    """End a process run: with ``output_dir`` the rows of ``res.history`` as
    ``{name}_diagnostics.csv``, the pictures (``draw()`` returns their paths) and the VTK series'
    path; close the simulation. Returns ``res``."""
    if output_dir and res.history:
        res.csv = write_rows(comm, os.path.join(output_dir, f"{name}_diagnostics.csv"),
                             res.history)
        if pictures:
            res.pictures = draw()
        if vtk_every:
            res.vtk = os.path.join(output_dir, f"{name}.pvd")
    res.contacts = contact_lines(sim)
    sim.close()
    return res


def steady_values(rows: Sequence[dict], first: int, last: int, keys: Sequence[str]) -> dict:
    """Means of ``keys`` over the rows ``first..last`` (the steady window), the half
    peak-to-peak oscillation of each relative to its mean (``{key}_oscillation``), and the
    window itself (``steady_from``, ``steady_to``, ``steady_time``)."""
    sel = rows[first:last + 1]
    out = dict(steady_from=first, steady_to=last,
               steady_time=(rows[first]["time"], rows[last]["time"]))
    for key in keys:
        vals = [q[key] for q in sel]
        mean = float(np.mean(vals))
        out[key] = mean
        out[f"{key}_oscillation"] = float(np.ptp(vals) / (2.0 * abs(mean))) if mean else 0.0
    return out


def vertex_field(sim, values) -> np.ndarray:
    """Per-vertex ``values`` (local vertices, e.g. ``sim.w.x.array[sim.space.vertex_dofs]``)
    as an array over the mesh's geometry nodes, for :func:`meridian_section`."""
    out = np.zeros((sim.mesh.geometry.x.shape[0],) + np.shape(values)[1:])
    out[sim.space.vertex_geometry] = values
    return out


def meridian_section(comm, sim, facet_tags, tag, fields) -> tuple:
    """The triangles of a symmetry face through the axis (z): the (z, r) coordinates of their
    vertices, (N, 3, 2), and per triangle the value of each of ``fields``: a cell function
    (the cell behind the triangle) or an array over the geometry nodes
    (:func:`vertex_field`, averaged over the triangle's vertices); gathered on every rank."""
    msh = sim.mesh
    facets = facet_tags.indices[facet_tags.values == tag]
    msh.topology.create_connectivity(2, 3)
    f2c = msh.topology.connectivity(2, 3)
    tri = compat.entities_to_geometry(msh, 2, facets)
    x = msh.geometry.x
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int64)
    zr = np.stack([x[tri][..., 2], np.hypot(x[tri][..., 0], x[tri][..., 1])], -1)
    vals = [f[tri].mean(axis=1) if isinstance(f, np.ndarray) else f.x.array[cells]
            for f in fields]
    return gather(comm, zr.reshape(-1, 3, 2)), [gather(comm, v) for v in vals]


def plot_sections(path, zr, panels, outline=None, title="", r_max=None, dpi=120,
                  xlabel="z [mm]"):
    """Meridian sections (rank 0): one panel per ``(values, label, colormap)`` or ``(values,
    label, colormap, (vmin, vmax))`` of the triangles ``zr`` of :func:`meridian_section`, each
    with the ``outline`` curve ``(s, r, label)`` (a tool's profile), equal axes, the figure
    sized to the section; saved to ``path``."""
    plt = pyplot()
    from matplotlib.collections import PolyCollection

    z0, z1 = zr[..., 0].min() - 1, zr[..., 0].max() + 1
    r1 = r_max or 1.1 * zr[..., 1].max()
    width = 11.0
    height = len(panels) * (0.8 + 0.8 * width * r1 / (z1 - z0)) + 0.6
    fig, axs = plt.subplots(len(panels), 1, figsize=(width, height), sharex=True,
                            squeeze=False)
    axs = axs[:, 0]
    for ax, (val, lab, cmap, *lim) in zip(axs, panels):
        pc = PolyCollection(zr, array=val, cmap=cmap, edgecolors="face", linewidths=0.2)
        if lim:
            pc.set_clim(*lim[0])
        ax.add_collection(pc)
        fig.colorbar(pc, ax=ax, label=lab, fraction=0.05, pad=0.01)
        if outline is not None:
            ax.plot(outline[0], outline[1], "k-", lw=1.5, label=outline[2])
            ax.legend(loc="upper left", fontsize=8)
        ax.set_ylim(0, r1)
        ax.set_aspect("equal")
        ax.set_ylabel("r [mm]")
    axs[0].set_xlim(z0, z1)
    axs[-1].set_xlabel(xlabel)
    axs[0].set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def plot_curves(ax, t, curves, bands=(), window=None, ylabel="", ylim=None):
    """One axis of history curves: ``curves`` ``[(values, style, label)]`` against ``t``,
    horizontal ``bands`` ``[(value, style, label)]`` (theory), the steady ``window``
    ``(t0, t1)`` shaded."""
    for vals, style, label in curves:
        ax.plot(t, vals, style, label=label)
    for val, style, label in bands:
        ax.axhline(val, color="k", ls=style, label=label)
    if window is not None:
        ax.axvspan(window[0], window[1], color="y", alpha=0.3, label="steady window")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)


def write_rows(comm, path: Optional[str], rows: Sequence[dict]) -> Optional[str]:
    """The rows as a CSV file (rank 0 writes; the directory is created)."""
    if not path or not rows:
        return None
    if comm.rank == 0:
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        with open(path, "w", newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
    return path


# ---- a case's flow-stress material and heat (the fields ``material`` and ``heat``)

def check_output_dir(output_dir, comm) -> None:
    """Before the first increment of a process run (collective): ``output_dir`` must be a
    directory that exists or can be made and is writable, the same on every rank; else a
    ValueError on every rank (not after the whole run, nor a hang)."""
    with together(comm, "the process run's output_dir",
                  output_dir=None if output_dir is None else os.path.abspath(str(output_dir))):
        problem = output_dir_problem(output_dir)
        if problem:
            raise ValueError(f"output_dir {str(output_dir)!r} {problem}: give a directory "
                             f"path (checked before the run, nothing was computed)")


def mean_norton_hoff(material: Viscoplastic, strain: float, rate: float,
                     temperature: Optional[float] = None):
    """(K, m) of the Norton–Hoff law whose flow stress at ``rate`` [1/s] is the material's
    mean flow stress over the strain 0..``strain`` (the classical σ̄ of slab and upper-bound
    theories with hardening) at ``temperature`` [°C] (default the material's), m the local
    rate sensitivity there."""
    T = material.temperature if temperature is None else temperature
    T = 20.0 if T is None else T
    e = np.linspace(0.0, strain, 201)
    s = material.flow.sigma0(e, rate, T)
    mean = float(np.sum(0.5 * (s[1:] + s[:-1]) * np.diff(e)) / strain)
    m = float(np.mean(material.flow.rate_sensitivity(e, rate, T)))
    return mean / (math.sqrt(3.0) * (math.sqrt(3.0) * rate) ** m), m


def check_material_heat(material, heat):
    """ValueError unless ``material`` is None or a :class:`~fxcontact.Viscoplastic` and
    ``heat`` None or a :class:`~fxcontact.HeatSetup` (a case's ``__post_init__``)."""
    if material is not None and not isinstance(material, Viscoplastic):
        raise ValueError(f"material must be a fxcontact.Viscoplastic (a flow stress; "
                         f"plain Norton-Hoff: K and m), got {material!r}")
    if heat is not None and not isinstance(heat, HeatSetup):
        raise ValueError(f"heat must be a fxcontact.HeatSetup, got {heat!r}")


def theory_temperature(case) -> Optional[float]:
    """The temperature [°C] of a case's theory: the heat's initial temperature, else the
    material's (None: the material's own default)."""
    return case.heat.initial_temperature if case.heat is not None else None


def material_text(case, body: str = "workpiece") -> str:
    """The report's phrase of the material: ``K .. m ..`` (Norton–Hoff), or the flow stress's
    class with its temperature, the ``body``'s initial temperature and the heated tools."""
    if case.material is None:
        return f"K {case.K:g} m {case.m:g}"
    T = case.material.temperature
    text = f"{type(case.material.flow).__name__} flow stress" + (
        f" at {T:g} °C" if T is not None and case.heat is None else "")
    if case.heat is not None:
        text += (f", {body} at {case.heat.initial_temperature:g} °C, tools "
                 f"{sorted(case.heat.tools or {})}")
    return text


def heat_columns(r: dict) -> Dict[str, float]:
    """The heat's columns (``heat_*``) of a :class:`~fxcontact.Simulation` history row."""
    return {k: v for k, v in r.items() if k.startswith("heat_")}


def heat_lines(history: Sequence[dict], heat, body: str = "workpiece") -> list:
    """The report's line of the temperature at the end (min, mean, max) and of the run's heat
    balance [J] (the sums of the increments' ``heat_*`` columns), if the run has heat."""
    q = history[-1] if history else {}
    if "heat_T_mean" not in q:
        return []
    tot = {k: sum(r[f"heat_{k}"] for r in history) / 1e3
           for k in ("generated", "friction", "tools", "air", "radiation", "stored",
                     "residual")}
    return [f"{body} temperature at the end: min {q['heat_T_min']:.0f} / mean "
            f"{q['heat_T_mean']:.0f} / max {q['heat_T_max']:.0f} °C (from "
            f"{heat.initial_temperature:g}); heat of the model [J]: plastic work "
            f"{tot['generated']:.3g} + friction {tot['friction']:.3g} + tools "
            f"{tot['tools']:.3g} + air {tot['air'] + tot['radiation']:.3g} = stored "
            f"{tot['stored']:.3g} (balance residual {tot['residual']:.1e})"]
