"""The ring-compression friction test (THEORY §9, §14.5): FE calibration curves against
Avitzur's upper bound, for several Tresca friction factors m̄.

A flat ring (outer radius R_o, inner radius R_i, height H in mm; default the 6:3:2 ring
60:30:20) is compressed between two flat dies with Tresca friction ``τ = m̄ k`` (k = σ₀/√3 of
the Norton–Hoff law at the node's strain rate). With little friction the hole grows, with much
friction the material near the bore flows inwards and the hole shrinks: the change of the
inner diameter against the height reduction, for a range of m̄, is the calibration chart of
the ring test, put next to Avitzur's upper-bound curves
(:func:`fxcontact.theory.forming.ring_compression_upper_bound`).

**Model** (:func:`run_ring`). One eighth of the ring (:func:`fxcontact.meshing.ring`,
``sector="eighth"``): symmetry planes x = 0, y = 0 and the mid-plane z = 0. The upper die is a
rigid :class:`~fxcontact.tools.analytic.Plane` moving down at half the closing speed; nodal
penalty contact (implicit scheme, implicit friction) on the top face, and frictionless contact
with the same plane on the bore and the outer surface, which fold over onto the die at large
reductions (in one contact with the top face, the lumped area of an edge node would include its
share of the lateral surface and inflate its friction force). Norton–Hoff (K in MPa·s^m, m),
MINI elements, updated Lagrangian. A start-up increment of :data:`STARTUP` × dt comes first
(the nodal Tresca k comes from the increment's predictor, the rest state in the first
increment); its force is not reported. The slip regularisation v₀ is the contact's default
(10⁻³ × the process speed) unless ``slip_velocity`` is given.

**Measured.** Three inner diameters, as % change of the initial one: the **minimum** over the
bore (the smallest node radius: the chart's, what a gauge measures), the one at mid-height and
the one at the die face (mean radius of the bore nodes there). The die force is reported as
``F/(σ₀ A₀)`` (A₀ the initial annulus, σ₀ at the mean strain rate v/T of the current height
T), next to the upper bound's ``J/(v σ₀ A₀)``.

Example::

    from fxcontact.processes import ring_test
    res = ring_test.run(mbars=(0.0, 1.0), h=5.0, reduction=0.2, n_steps=2, output_dir=None)
    print(res["fe"][1.0]["id_min"][-1], res["ub"][1.0]["id_change"][-1])
"""

from __future__ import annotations

import csv
import os
import time

import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Tresca
from fxcontact.contact.nodal import NodalContact
from fxcontact.io.series import pyplot
from fxcontact.materials import NortonHoff
from fxcontact.meshing import RING_TAGS, ring
from fxcontact.newton.solver import SolverOptions
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.theory.forming import flow_stress, ring_compression_upper_bound
from fxcontact.tools.analytic import Plane

__all__ = ["MBARS", "STARTUP", "run_ring", "run", "plot_chart"]

#: default friction factors of the chart
MBARS = (0.0, 0.1, 0.2, 0.4, 0.7, 1.0)
#: length of the start-up increment, as a fraction of the others (module docstring)
STARTUP = 0.05


def run_ring(mbar: float, *, outer_radius, inner_radius, height, h, K, m, speed, reduction,
             n_steps, slip_velocity, line_search, output_dir, progress, comm) -> dict:
    """Compress the eighth ring with Tresca friction ``mbar`` (the model of the module
    docstring); the arguments are those of :func:`run` (lengths mm, speed mm/s, K MPa·s^m).
    With ``output_dir``, the ring's CSV history and VTK series go to ``output_dir/mbar_<m̄>``.

    Returns:
        dict with ``mbar``, per tracked point (the start, then the end of each increment, the
        start-up's included; arrays) ``reduction`` (height reduction), ``id_min``, ``id_mid``,
        ``id_face`` (% change of the inner diameter: minimum over the bore, at mid-height, at
        the die face), per increment ``force_reduction`` (the reduction at its start) and
        ``force`` (F/(σ₀A₀), NaN at the start point and for the start-up increment), the
        ``history``, the total ``newton_iterations`` and ``cutbacks``.
    """
    Ro, Ri, H = outer_radius, inner_radius, height
    msh, _, ft = ring(comm, Ro, Ri, H, h, sector="eighth")
    space = MixedSpace(msh)
    name = f"mbar_{mbar:g}"
    sim = Simulation(space, NortonHoff(K=K, m=m, regularization=1e-4 * speed / H),
                     solver_options=SolverOptions(line_search=line_search),
                     output_dir=None if output_dir is None else os.path.join(output_dir, name),
                     name=name, progress=progress)
    sim.add_velocity_bc(sim.facets(ft, RING_TAGS["symmetry_x"]), 0.0, 0)
    sim.add_velocity_bc(sim.facets(ft, RING_TAGS["symmetry_y"]), 0.0, 1)
    sim.add_velocity_bc(sim.facets(ft, RING_TAGS["mid_plane"]), 0.0, 2)
    die = Plane(point=(0.0, 0.0, 0.5 * H), normal=(0.0, 0.0, -1.0),
                velocity=(0.0, 0.0, -0.5 * speed), name="die")
    sim.add_contributor(NodalContact(ContactBoundary(space, ft, RING_TAGS["top"]), die,
                                     scheme="implicit", friction=Tresca(mbar),
                                     slip_velocity=slip_velocity, name="contact"))
    # fold-over of the bore and the outer surface onto the die: frictionless contact with the
    # same plane (module docstring)
    fold = Plane(die.point, die.normal, velocity=(0.0, 0.0, -0.5 * speed), name="die_fold")
    sim.add_contributor(NodalContact(ContactBoundary(space, ft, [RING_TAGS["inner"],
                                                                 RING_TAGS["outer"]]),
                                     fold, scheme="implicit", name="fold"))
    bore = ContactBoundary(space, ft, RING_TAGS["inner"]).vertices   # owned bore vertices
    tol = 1e-3 * h

    def measure():
        x = sim.vertex_positions()
        top = comm.allreduce(np.max(x[:, 2], initial=-np.inf), op=MPI.MAX)
        xb = x[bore]
        rb = np.hypot(xb[:, 0], xb[:, 1])
        mid = np.abs(xb[:, 2]) < tol
        face = xb[:, 2] > top - tol

        def mean(sel):
            s = comm.allreduce(np.array([np.sum(rb[sel]), np.sum(sel)], float), op=MPI.SUM)
            return s[0] / s[1] if s[1] > 0 else np.nan

        return (comm.allreduce(np.min(rb, initial=np.inf), op=MPI.MIN), mean(mid), mean(face),
                sim.t)

    rows = [measure()]
    t_end = reduction * H / speed
    dt = t_end / n_steps
    # start-up increment (its nodal Tresca limits come from the rest state), then n_steps
    sim.run(STARTUP * dt, STARTUP * dt, close=False, callback=lambda s, res: rows.append(measure()))
    sim.run(t_end, dt, callback=lambda s, res: rows.append(measure()))
    rows = np.array(rows)
    hist = sim.history
    T = H - speed * rows[:, 3]          # current height (die position)
    # force on the dies (full ring: 4 quarters; the half height carries the whole force) on
    # each increment's initial geometry (updated Lagrangian)
    F = np.array([4.0 * (row["die_force_z"] + row["die_fold_force_z"]) for row in hist])
    A0 = np.pi * (Ro ** 2 - Ri ** 2)
    force = np.r_[np.nan, F / (flow_stress(K, m, speed / T[:-1]) * A0)]
    force[1] = np.nan   # the start-up increment (friction limits at the rest state's rate)
    return {"mbar": mbar, "reduction": 1.0 - T / H,
            "id_min": 100.0 * (rows[:, 0] / Ri - 1.0), "id_mid": 100.0 * (rows[:, 1] / Ri - 1.0),
            "id_face": 100.0 * (rows[:, 2] / Ri - 1.0),
            # the force of increment k acts on the geometry at the start of the increment
            "force_reduction": np.r_[np.nan, 1.0 - T[:-1] / H], "force": force,
            "history": hist, "newton_iterations": int(sum(r["newton_iterations"] for r in hist)),
            "cutbacks": int(sum(r["cutbacks"] for r in hist))}


def run(outer_radius=30.0, inner_radius=15.0, height=20.0, h=2.5, K=50.0, m=0.15, speed=10.0,
        reduction=0.5, n_steps=25, mbars=MBARS, slip_velocity=None, line_search="bt",
        output_dir="results/ring_test", picture=True, progress=True,
        comm=MPI.COMM_WORLD) -> dict:
    """FE ring-compression curves for each m̄ of ``mbars`` and Avitzur's upper-bound curves.

    Args:
        outer_radius, inner_radius, height: the ring [mm] (default the 6:3:2 ring 60:30:20).
        h: element size [mm].
        K [MPa·s^m], m: Norton–Hoff parameters.
        speed: closing speed of the dies [mm/s] (each die moves at half of it).
        reduction: final height reduction (fraction); n_steps: increments.
        mbars: Tresca friction factors in [0, 1].
        slip_velocity: regularisation v₀ of the slip speed [mm/s] (default: the contact's,
            10⁻³ × the process speed of the increment).
        line_search: Newton line search (``"bt"``: backtracking, ``"basic"``: full steps).
        output_dir: where the outputs go (None: nothing written): ``ring_test.csv`` (the FE
            and upper-bound curves), ``ring_test.png`` (:func:`plot_chart`) and per m̄ a CSV
            history and a VTK series in ``mbar_<m̄>/``.
        picture: draw ``ring_test.png``.
        progress: log the increments.
        comm: the MPI communicator.
    Returns:
        dict with ``fe`` (per m̄: ``reduction``, ``id_min``, ``id_mid``, ``id_face`` (% change
        of the inner diameter: minimum over the bore, at mid-height, at the die face),
        ``force_reduction``, ``force`` (F/(σ₀A₀)), history, Newton iterations, cut-backs,
        ``wall_time`` [s]), ``ub`` (per m̄: the upper bound at the FE reductions: ``id_change``,
        ``neutral_radius``, ``pressure`` and ``force`` = J/(vσ₀A₀)), ``diff`` (per m̄: FE − UB
        of the minimum inner diameter change, in percentage points, and of the force), the
        ``table`` rows written to the CSV, the ``parameters`` and the output paths ``csv``,
        ``png`` (rank 0; None elsewhere and without ``output_dir``).
    """
    if not (0 < inner_radius < outer_radius and height > 0 and h > 0 and speed > 0):
        raise ValueError("need 0 < inner_radius < outer_radius, height > 0, h > 0, speed > 0")
    if not (0 < reduction < 0.8 and n_steps >= 1):
        raise ValueError("need 0 < reduction < 0.8 and n_steps >= 1")
    mbars = [float(x) for x in mbars]
    if not mbars or any(not 0.0 <= x <= 1.0 for x in mbars):
        raise ValueError(f"mbars must be friction factors in [0, 1], got {mbars!r}")
    if output_dir is not None and comm.rank == 0:
        os.makedirs(output_dir, exist_ok=True)
    common = dict(outer_radius=outer_radius, inner_radius=inner_radius, height=height, h=h, K=K,
                  m=m, speed=speed, reduction=reduction, n_steps=n_steps,
                  slip_velocity=slip_velocity, line_search=line_search, output_dir=output_dir,
                  progress=progress, comm=comm)
    fe, ub, diff, table = {}, {}, {}, []
    A0 = np.pi * (outer_radius ** 2 - inner_radius ** 2)
    for mb in mbars:
        t0 = time.perf_counter()
        r = run_ring(mb, **common)
        r["wall_time"] = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        fe[mb] = r
        u = ring_compression_upper_bound(outer_radius, inner_radius, height, mb, r["reduction"])
        # force of increment k: on the geometry at the start of the increment (point k − 1)
        J = u["pressure"] * np.pi * (u["outer_radius"] ** 2 - u["inner_radius"] ** 2) / A0
        u["force"] = np.r_[np.nan, J[:-1]]
        ub[mb] = u
        diff[mb] = {"id_min": r["id_min"] - u["id_change"], "force": r["force"] - u["force"]}
        for k in range(len(r["reduction"])):
            table.append({"mbar": mb, "reduction": r["reduction"][k],
                          "id_min_fe": r["id_min"][k], "id_mid_fe": r["id_mid"][k],
                          "id_face_fe": r["id_face"][k], "id_ub": u["id_change"][k],
                          "neutral_radius_ub": u["neutral_radius"][k],
                          "force_reduction": r["force_reduction"][k], "force_fe": r["force"][k],
                          "force_ub": u["force"][k]})
    out = {"fe": fe, "ub": ub, "diff": diff, "table": table, "csv": None, "png": None,
           "parameters": {k: v for k, v in common.items() if k != "comm"}}
    if output_dir is not None and comm.rank == 0:
        out["csv"] = os.path.join(output_dir, "ring_test.csv")
        with open(out["csv"], "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(table[0].keys()))
            w.writeheader()
            w.writerows(table)
        if picture:
            out["png"] = plot_chart(fe, ub, os.path.join(output_dir, "ring_test.png"),
                                    (outer_radius, inner_radius, height))
    return out


def plot_chart(fe: dict, ub: dict, path: str, ring_size) -> str:
    """Calibration chart (% change of the minimum inner diameter vs % height reduction) and the
    die force, FE (solid, markers) and upper bound (dashed, same colour) for each m̄.

    Args:
        fe, ub: the ``fe`` and ``ub`` dicts of :func:`run` (per m̄).
        path: the PNG to write (call on one rank).
        ring_size: ``(outer_radius, inner_radius, height)`` [mm], for the title.
    Returns:
        ``path``.
    """
    plt = pyplot()
    from matplotlib.lines import Line2D

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5))
    colors = plt.get_cmap("tab10").colors
    keys = list(fe)
    for i, mb in enumerate(keys):
        c = colors[i % len(colors)]
        r, u = fe[mb], ub[mb]
        ax1.plot(100 * r["reduction"], r["id_min"], "-o", color=c, ms=3.5, lw=1.6,
                 label=f"m̄ = {mb:g}")
        ax1.plot(100 * r["reduction"], u["id_change"], "--", color=c, lw=1.4)
        ax2.plot(100 * r["force_reduction"], r["force"], "-o", color=c, ms=3.5, lw=1.6,
                 label=f"m̄ = {mb:g}")
        ax2.plot(100 * r["force_reduction"], u["force"], "--", color=c, lw=1.4)
    Ro, Ri, H = ring_size
    ax1.axhline(0.0, color="0.5", lw=0.8)
    ax1.set_xlabel("height reduction [%]")
    ax1.set_ylabel("change of the minimum inner diameter [%]")
    ax1.set_title(f"Ring test {2 * Ro:g}:{2 * Ri:g}:{H:g} mm, Tresca friction m̄")
    ax2.set_xlabel("height reduction [%]")
    ax2.set_ylabel(r"die force $F/(\sigma_0 A_0)$")
    ax2.set_title(r"Die force ($\sigma_0$ at $\dot{\bar\varepsilon}=v/T$, $A_0$ initial annulus)")
    style = [Line2D([], [], color="k", marker="o", ms=3.5, label="FE"),
             Line2D([], [], color="k", ls="--", label="upper bound (Avitzur)")]
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        h, lab = ax.get_legend_handles_labels()
        ax.legend(handles=h + style, fontsize=8.5, loc="best", ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
