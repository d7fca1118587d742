"""Pictures of a ring rolled by :func:`fxcontact.processes.ring_rolling.run`: the top view of the
ring and the tools at four times, and the diameters, roll forces and rotation speeds against
time."""

from __future__ import annotations

import math
import os

import numpy as np
from mpi4py import MPI

from fxcontact.io.series import pyplot
from fxcontact.thermal import WorkpieceHeat

__all__ = ["snapshot", "pictures", "top_view_png", "curves_png"]


def snapshot(setup, center) -> dict:
    """Top-face outline (outer and inner surface nodes, z ≥ 90 % of the top) and the tool
    circles of a :class:`~fxcontact.processes.ring_rolling.RingRollingSetup` now (gathered on
    every rank; collective)."""
    sim, comm, t = setup.sim, setup.sim.comm, setup.sim.t
    X = sim.vertex_positions()
    zmax = comm.allreduce(float(np.max(X[:, 2], initial=-np.inf)), op=MPI.MAX)
    pts = []
    for b in (setup.outer, setup.inner):
        x = X[b.vertices]
        x = x[x[:, 2] > 0.9 * zmax]
        pts.append(np.concatenate(comm.allgather(x[:, :2])))
    circ = [(tl.name, *tl.motion.axis_point_at(t)[:2], tl.motion.angle(t))
            for tl in setup.tools]
    out = dict(t=t, outer=pts[0], inner=pts[1], tools=circ, center=np.array(center))
    heat = [c for c in sim.controllers if isinstance(c, WorkpieceHeat)]
    if heat:   # the top face's temperature (the face a camera above the mill sees)
        v = setup.top.vertices
        T = heat[0].temperature.x.array[heat[0].problem.dofs_of_vertices(v)]
        out["top"] = np.concatenate(comm.allgather(np.column_stack([X[v][:, :2], T])))
    return out


def _outline(ax, p, center):
    """The closed outline of points ``p`` sorted by angle about ``center``."""
    if len(p):
        o = np.argsort(np.arctan2(p[:, 1] - center[1], p[:, 0] - center[0]))
        q = np.vstack([p[o], p[o][:1]])
        ax.plot(q[:, 0], q[:, 1], "-", color="C0", lw=1.2)


def _temperature(ax, top, limits):
    """The temperature of the top face's points (x, y, T), smoothly shaded on their Delaunay
    triangulation with the triangles across the bore (edges far longer than the mesh's)
    masked."""
    from matplotlib.tri import Triangulation
    tri = Triangulation(top[:, 0], top[:, 1])
    p = np.column_stack([top[:, 0], top[:, 1]])[tri.triangles]
    edge = np.max(np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2), axis=1)
    tri.set_mask(edge > 3.0 * np.median(edge))
    return ax.tripcolor(tri, top[:, 2], shading="gouraud", cmap="inferno", vmin=limits[0],
                        vmax=limits[1])


def _cone(ax, g, x, y):
    """The upper cone seen from above: its footprint from s0 to s1 along the mill line
    (half-opening α about the generatrix), hatched, apex marked."""
    th = math.atan(math.tan(g["alpha"]) * math.cos(g["alpha"]))
    c, s = math.cos(th), math.sin(th)
    px = [x - g["s0"] * c, x - g["s1"] * c, x - g["s1"] * c, x - g["s0"] * c]
    py = [y + g["s0"] * s, y + g["s1"] * s, y - g["s1"] * s, y - g["s0"] * s]
    ax.fill(px, py, facecolor="tab:orange", alpha=0.25, edgecolor="tab:orange", hatch="//",
            lw=1.0, label="cone (above the ring)")
    ax.plot([x, x - g["s1"] * c], [y, y], color="tab:orange", lw=1.2, ls="--")
    ax.plot(x, y, marker="^", color="tab:orange", ms=7)


def top_view_png(res, snaps, path) -> str:
    """The ring's top face (outline of the outer and bore surfaces) and the tools (grey, a black
    radius showing the tool's angle) at the snapshots' times."""
    plt = pyplot()
    c = res.case
    radii = {"main_roll": c.R1, "mandrel": c.R2, "guide1": c.Rg, "guide2": c.Rg}
    n = len(snaps)
    nc = 2 if n > 1 else 1
    nr = (n + nc - 1) // nc
    fig, axs = plt.subplots(nr, nc, figsize=(6.2 * nc, 4.4 * nr), squeeze=False)
    for ax in axs.ravel()[n:]:
        ax.axis("off")
    hot = [s["top"] for s in snaps if "top" in s]
    limits = None
    if hot:
        allT = np.concatenate([h[:, 2] for h in hot])
        limits = (allT.min(), max(allT.max(), allT.min() + 1.0))
    for ax, s in zip(axs.ravel(), snaps):
        if "top" in s:
            art = _temperature(ax, s["top"], limits)
        _outline(ax, s["outer"], s["center"])
        _outline(ax, s["inner"], s["center"])
        for nm, x, y, ang in s["tools"]:
            if nm == "cone":
                _cone(ax, res.cone_geometry, x, y)
                continue
            rad = radii.get(nm, 10.0)
            th = np.linspace(0, 2 * np.pi, 200)
            ax.fill(x + rad * np.cos(th), y + rad * np.sin(th), color="0.75", alpha=0.6)
            ax.plot([x, x + rad * math.cos(ang)], [y, y + rad * math.sin(ang)], "k-", lw=0.8)
            ax.annotate(nm.replace("_", " "), (x, y), ha="center", va="center", fontsize=7)
        ax.plot(*s["center"][:2], "r+", ms=8)
        if res.cone_geometry:
            ax.legend(loc="lower left", fontsize=7)
        ax.set_aspect("equal")
        ax.set_xlim(-1.35 * c.R - 20, c.R + 2 * c.R1 + 10)
        ax.set_ylim(-1.6 * c.R, 1.6 * c.R)
        ax.set_title(f"t = {s['t']:.2f} s ({s['t'] / res.t_rev:.2f} rev)", fontsize=10)
        ax.set_xlabel("x [mm] (mill line)", fontsize=8)
        ax.tick_params(labelsize=8)
    fig.suptitle("ring rolling: top view (ring top face blue" + (", coloured by its temperature"
                                                              if hot else "")
                 + ", its centre +; tools grey, black line = tool angle"
                 + (", upper cone orange, apex ▲" if res.cone_geometry else "") + ")",
                 fontsize=10)
    fig.tight_layout()
    if hot:
        fig.subplots_adjust(right=0.88)
        cb = fig.colorbar(art, cax=fig.add_axes([0.9, 0.15, 0.015, 0.7]), format="%.0f")
        cb.set_label("temperature of the top face [°C]")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def curves_png(res, path) -> str:
    """Diameters, roll forces and rotation speeds against time."""
    plt = pyplot()
    h = res.history
    t = np.array([q["time"] for q in h])
    q0 = h[0]
    hot = "heat_T_mean" in q0
    fig, axs = plt.subplots(1, 4 if hot else 3, figsize=(20 if hot else 15, 4.3))
    ax = axs[0]
    for key, lab, st in (("outer_diameter", "outer D", "-"), ("inner_diameter", "inner d", "-"),
                         ("mean_diameter", "mean (D+d)/2", "-"),
                         ("mean_diameter_volume", "mean, volume constancy V/(πHB)", "k--")):
        ax.plot(t, [q[key] - q0[key] for q in h], st, label=lab)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("change since the first increment [mm]")
    ax.legend(fontsize=8)
    ax.set_title(f"diameters (initial D = {q0['outer_diameter']:.1f}, "
                 f"d = {q0['inner_diameter']:.1f} mm)", fontsize=10)
    ax = axs[1]
    ax.plot(t, [q["main_force_x"] / 1e3 for q in h], label="main roll, radial")
    ax.plot(t, [-q["mandrel_force_x"] / 1e3 for q in h], label="mandrel, radial")
    ax.plot(t, [q["guide_force"] / 1e3 for q in h], label="guide rolls (sum |F|)")
    if "cone_force" in q0:
        ax.plot(t, [q["cone_force"] / 1e3 for q in h], label="upper cone, axial")
        ax.plot(t, [q["cone_force_estimate"] / 1e3 for q in h], ":",
                label="cone, 2kBL_a estimate")
    ax.axhline(res.force_estimate / 1e3, color="k", ls="--", label="2kHLQ estimate")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("force [kN] (whole ring)")
    ax.legend(fontsize=8)
    ax.set_title(f"roll forces (sigma0 = {res.sigma0:.0f} MPa)")
    ax = axs[2]
    ax.plot(t, [q["ring_omega"] for q in h], label="ring ω")
    ax.plot(t, [q["ring_omega_nominal"] for q in h], "k--", label="main roll speed / R")
    ax.plot(t, [q["mandrel_omega"] * res.case.R2 / max(q["inner_diameter"] / 2, 1e-9)
                for q in h], ":", label="mandrel ω R₂ / r")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("rad/s")
    ax.legend(fontsize=8)
    ax.set_title("rotation speeds")
    if hot:
        _temperatures(axs[3], t, h, res.case.heat.initial_temperature)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _temperatures(ax, t, h, T0):
    """T(t): the ring's minimum, mean and maximum, and the probes (thermocouples) if any."""
    for key, lab, st in (("heat_T_max", "max", "r-"), ("heat_T_mean", "mean", "k-"),
                         ("heat_T_min", "min", "b-")):
        ax.plot(t, [q[key] for q in h], st, lw=1.5, label=lab)
    marks = iter("osd^v<>")   # markers: a probe on another curve stays visible
    for k in (k for k in h[0] if k.startswith("heat_T_at_")):
        ax.plot(t, [q[k] for q in h], "--", lw=1.0, marker=next(marks, "x"), ms=3.5,
                markevery=max(1, len(t) // 15), label=f"probe '{k[10:]}'")
    ax.axhline(T0, color="0.5", ls=":", lw=1.0, label=f"initial {T0:g} °C")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("temperature [°C]")
    ax.legend(fontsize=8)
    ax.set_title("ring temperature")


def pictures(res, snaps, out, name) -> dict:
    """``{"top_view": ..., "curves": ...}``: the PNGs written into ``out`` (rank 0)."""
    return dict(top_view=top_view_png(res, snaps, os.path.join(out, f"{name}_top.png")),
                curves=curves_png(res, os.path.join(out, f"{name}_curves.png")))
