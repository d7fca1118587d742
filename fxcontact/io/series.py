"""Outputs: a VTK time series that follows the moving mesh, a CSV history, PNG pictures (a
mesh by VTK, :func:`render_png`; curves by matplotlib, :func:`figure`).

``XDMFFile`` in dolfinx 0.5.2 keeps pointing at the first mesh written, so a moving mesh does not
show; ``VTKFile`` (``.pvd``) stores the current geometry at every step and ParaView opens it
directly. The CSV history is written by rank 0 and flushed after every increment, so a run that
stops early keeps everything computed so far.
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from typing import Dict, List, Optional, Sequence

import meshio
import numpy as np
from mpi4py import MPI

from fxcontact import compat

__all__ = ["SeriesWriter", "HistoryWriter", "render_png", "gather_mesh_data", "read_pvd", "pyplot",
           "write_pvd", "figure", "plot_pressure_profile"]

log = logging.getLogger(__name__)


class SeriesWriter:
    """VTK (.pvd) time series on the current (moving) mesh.

    ``VTKFile`` writes its ``.pvd`` index only when closed, so the index ``<name>.pvd`` is
    rewritten here (rank 0, atomically) after every step: a run that is killed keeps a readable
    series. With ``resume_time`` the series continues a previous one: its steps up to that time
    are kept, later ones (written after the checkpoint of a run that was then killed) dropped,
    and the new steps go to files ``<name>_r<k>…`` of a new segment ``k``.
    """

    def __init__(self, comm: MPI.Comm, directory: str, name: str,
                 resume_time: Optional[float] = None):
        make_directory(comm, directory)
        self.comm = comm
        self.directory = directory
        self.path = os.path.join(directory, f"{name}.pvd")
        self._entries: List[tuple] = []
        stem = name
        if resume_time is not None:
            data = None
            if comm.rank == 0:
                tol = 1e-12 * max(1.0, abs(resume_time))
                kept = [e for e in read_pvd(self.path) if e[0] <= resume_time + tol]
                k = 1
                while any(os.path.exists(os.path.join(directory, f"{name}_r{k}{suffix}"))
                          for suffix in (".pvd", "000000.pvtu")):
                    k += 1
                data = (kept, k)
            kept, k = comm.bcast(data, root=0)
            self._entries = list(kept)
            stem = f"{name}_r{k}"
        self._stem = stem
        self._count = 0
        self._f = compat.VTKFile(comm, os.path.join(directory, f"{stem}.pvd"), "w")

    def write(self, functions: Sequence, t: float):
        self._f.write_function(list(functions), float(t))
        self._entries.append((float(t), f"{self._stem}{self._count:06d}.pvtu"))
        self._count += 1
        if self.comm.rank == 0:
            write_pvd(self.path, self._entries)

    def close(self):
        if self._f is not None:
            self._f.close()
            self._f = None
            if self.comm.rank == 0:
                # VTKFile has just written its own index of this segment: keep the whole series
                seg = os.path.join(self.directory, f"{self._stem}.pvd")
                if os.path.abspath(seg) != os.path.abspath(self.path) and os.path.exists(seg):
                    os.remove(seg)
                write_pvd(self.path, self._entries)


def make_directory(comm: MPI.Comm, directory: str):
    """Create ``directory`` on rank 0; an OSError (a file in the way, no permission) is raised
    on every rank (collective)."""
    err = None
    if comm.rank == 0:
        try:
            os.makedirs(directory, exist_ok=True)
        except OSError as e:
            err = f"cannot create the output directory {directory!r}: {e}"
    err = comm.bcast(err, root=0)
    if err:
        raise OSError(err)


def read_pvd(path: str) -> List[tuple]:
    """``[(time, file), …]`` of a ``.pvd`` collection (empty if the file does not exist)."""
    if not os.path.exists(path):
        return []
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def write_pvd(path: str, entries: Sequence[tuple]):
    """Write a ``.pvd`` collection atomically (temporary file, then rename)."""
    lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="1.0">',
             "  <Collection>"]
    lines += [f'    <DataSet timestep="{t!r}" part="0" file="{f}" />' for t, f in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write("\n".join(lines))
    os.replace(tmp, path)


class HistoryWriter:
    """CSV history, one row per increment, written by rank 0 and flushed at once.

    ``rows``: rows already computed (a resumed run): the file is rewritten with them
    (atomically) and continued.
    """

    def __init__(self, comm: MPI.Comm, directory: str, name: str,
                 rows: Optional[Sequence[Dict[str, float]]] = None):
        self.comm = comm
        self.path = os.path.join(directory, f"{name}_history.csv")
        self._fh = None
        self._writer = None
        self._keys: Optional[List[str]] = None
        if comm.rank == 0:
            os.makedirs(directory, exist_ok=True)
            if rows:
                tmp = self.path + ".tmp"
                with open(tmp, "w", newline="") as fh:
                    self._keys = list(rows[0].keys())
                    w = csv.DictWriter(fh, fieldnames=self._keys, extrasaction="ignore")
                    w.writeheader()
                    for r in rows:
                        w.writerow({k: r.get(k, "") for k in self._keys})
                os.replace(tmp, self.path)
                self._fh = open(self.path, "a", newline="")
                self._writer = csv.DictWriter(self._fh, fieldnames=self._keys,
                                              extrasaction="ignore")
            else:
                self._fh = open(self.path, "w", newline="")

    def write(self, row: Dict[str, float]):
        if self.comm.rank != 0:
            return
        if self._keys is None:
            self._keys = list(row.keys())
            self._writer = csv.DictWriter(self._fh, fieldnames=self._keys, extrasaction="ignore")
            self._writer.writeheader()
        self._writer.writerow({k: row.get(k, "") for k in self._keys})
        self._fh.flush()

    def close(self):
        if self._fh is not None:
            self._fh.close()
            self._fh = None


def gather_mesh_data(msh, cell_values: Optional[np.ndarray] = None):
    """Gather owned cells (VTK topology), their geometry and cell values on rank 0.

    Returns ``(topology, cell_types, points, values)`` on rank 0 and ``None`` elsewhere.
    """
    topo, ctypes, x = compat.vtk_mesh(msh)
    ncells = len(ctypes)
    topo = topo.reshape(ncells, -1)
    vals = None if cell_values is None else np.asarray(cell_values)[:ncells]
    data = msh.comm.gather((topo, ctypes, x, vals), root=0)
    if msh.comm.rank != 0:
        return None
    tops, cts, pts, vs = [], [], [], []
    offset = 0
    for t, c, p, v in data:
        t = t.copy()
        t[:, 1:] += offset
        offset += p.shape[0]
        tops.append(t)
        cts.append(c)
        pts.append(p)
        vs.append(v)
    values = None if cell_values is None else np.concatenate(vs)
    return np.concatenate(tops).ravel(), np.concatenate(cts), np.concatenate(pts), values


def render_png(msh, path: str, cell_values: Optional[np.ndarray] = None,
               scalar_name: str = "value", extra_meshes: Sequence = (), title: str = "",
               camera: Optional[str] = None, window_size=(1200, 900),
               show_edges: bool = True, clim=None) -> bool:
    """Render the mesh (coloured by a cell field) offscreen to a PNG. Collective; rank 0 writes.

    The picture is made by pyvista in a separate process (:mod:`fxcontact.io._render`): in a process
    that has loaded dolfinx, the VTK wheel's text rendering (scalar bar, titles) crashes on a
    library clash, so the gathered mesh is handed over as a ``.vtu`` file.

    Args:
        msh: the dolfinx mesh (current geometry).
        path: PNG file.
        cell_values: per-cell values (local cells, owned first) to colour by.
        extra_meshes: ``(points (N,3), triangles (M,3))`` surfaces (e.g. tools) drawn in grey.
        camera: "iso" (default), "xy", "xz" or "yz".
    Returns:
        True on rank 0 if the picture was written.
    """
    data = gather_mesh_data(msh, cell_values)
    if msh.comm.rank != 0:
        return False

    topo, ctypes, pts, vals = data
    if pts.shape[1] == 2:
        pts = np.c_[pts, np.zeros(len(pts))]
    cells = _vtk_to_meshio(topo, ctypes)
    out = os.path.abspath(path)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        cd = {} if vals is None else {scalar_name: [np.asarray(vals, dtype=np.float64)]}
        meshio.write(os.path.join(tmp, "body.vtu"), meshio.Mesh(pts, cells, cell_data=cd))
        extras = []
        for k, (p, t) in enumerate(extra_meshes):
            f = os.path.join(tmp, f"tool{k}.vtu")
            meshio.write(f, meshio.Mesh(np.asarray(p, float), [("triangle", np.asarray(t))]))
            extras.append(f)
        opts = dict(body=os.path.join(tmp, "body.vtu"), extras=extras, png=out,
                    scalar=scalar_name if vals is not None else None, title=title,
                    camera=camera or "iso", window_size=list(window_size),
                    show_edges=show_edges, clim=clim)
        spec = os.path.join(tmp, "spec.json")
        with open(spec, "w") as fh:
            json.dump(opts, fh)
        env = dict(os.environ)
        env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        for k in list(env):  # the child is not an MPI process
            if k.startswith(("OMPI_COMM", "PMIX_", "OMPI_MCA_ess", "OMPI_MCA_orte")):
                env.pop(k)
        # the script by its path, not ``-m fxcontact.io._render``: that would import the package
        # first, and with it dolfinx
        script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "_render.py")
        r = subprocess.run([sys.executable, script, spec], env=env,
                           capture_output=True, text=True, timeout=300)
    if r.returncode != 0 or not os.path.exists(out):
        log.warning("picture %s not written: %s", path, r.stderr[-2000:])
        return False
    return True


_VTK_TO_MESHIO = {5: "triangle", 10: "tetra", 3: "line", 9: "quad", 12: "hexahedron"}


def _vtk_to_meshio(topo: np.ndarray, ctypes: np.ndarray):
    """Flat VTK connectivity ``[n, i0, …, n, …]`` → meshio cell blocks."""
    blocks, pos = {}, 0
    for ct in ctypes:
        n = topo[pos]
        blocks.setdefault(_VTK_TO_MESHIO[int(ct)], []).append(topo[pos + 1: pos + 1 + n])
        pos += n + 1
    return [(k, np.array(v)) for k, v in blocks.items()]


def pyplot():
    """``matplotlib.pyplot`` with the non-interactive Agg backend, for pictures written to files.
    Imported here, on the first picture: matplotlib is needed for pictures only."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


@contextlib.contextmanager
def figure(path: str, figsize=(7.0, 4.5), dpi: int = 120, **subplots):
    """A matplotlib figure (Agg backend) saved to ``path`` when the block ends, then closed::

        with fx.figure("out.png") as (fig, ax):
            ax.plot(x, y)

    ``subplots`` go to ``plt.subplots`` (``ncols=2``: ``ax`` is then the array of axes). Not
    collective: draw on the rank that writes (rank 0). The figure is closed on an error too,
    and nothing is saved then."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=figsize, **subplots)
    try:
        yield fig, ax
        fig.tight_layout()
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)


def plot_pressure_profile(ax, a: float, p0: float, profiles: Sequence[tuple],
                          variable: str = "r", extent: Optional[tuple] = None):
    """Nodal contact pressures against Hertz's elliptic profile p₀ √(1 − s²/a²) (line or point
    contact), over p₀ against s/a on ``ax``, with a grid: ``profiles`` are
    ``(s, p, plot_kwargs)`` (the nodes' distance from the centre and pressure; the nodes within
    2a are drawn as markers, ``"o"`` by default); ``variable`` names s in the labels (``"x"``,
    ``"r"``); ``extent`` ``(s, label)``: the computed contact's extent, a dashed line."""
    ss = np.linspace(0.0, a, 400)
    ax.plot(ss / a, np.sqrt(1.0 - (ss / a) ** 2), "k-",
            label=f"Hertz, $p_0\\sqrt{{1-{variable}^2/a^2}}$")
    for s, p, kw in profiles:
        s, p = np.asarray(s), np.asarray(p)
        sel = s < 2.0 * a
        kw = dict(kw)
        ax.plot(s[sel] / a, p[sel] / p0, kw.pop("marker", "o"), **kw)
    if extent is not None:
        ax.axvline(extent[0] / a, color="C1", ls="--", lw=1, label=extent[1])
    ax.grid(alpha=0.3)
    ax.set_xlabel(f"${variable}/a$")
    ax.set_ylabel("$p/p_0$")
    ax.set_xlim(0, 1.5)
