"""Outputs: a VTK time series that follows the moving mesh, a CSV history, PNG pictures.

``XDMFFile`` in dolfinx 0.5.2 keeps pointing at the first mesh written, so a moving mesh does not
show; ``VTKFile`` (``.pvd``) stores the current geometry at every step and ParaView opens it
directly. The CSV history is written by rank 0 and flushed after every increment, so a run that
stops early keeps everything computed so far.
"""

from __future__ import annotations

import csv
import logging
import os
from typing import Dict, List, Optional, Sequence

import numpy as np
from mpi4py import MPI

from fxcontact import compat

__all__ = ["SeriesWriter", "HistoryWriter", "render_png", "gather_mesh_data"]

log = logging.getLogger(__name__)


class SeriesWriter:
    """VTK (.pvd) time series on the current (moving) mesh."""

    def __init__(self, comm: MPI.Comm, directory: str, name: str):
        if comm.rank == 0:
            os.makedirs(directory, exist_ok=True)
        comm.barrier()
        self.path = os.path.join(directory, f"{name}.pvd")
        self._f = compat.VTKFile(comm, self.path, "w")

    def write(self, functions: Sequence, t: float):
        self._f.write_function(list(functions), float(t))

    def close(self):
        if self._f is not None:
            self._f.close()
            self._f = None


class HistoryWriter:
    """CSV history, one row per increment, written by rank 0 and flushed at once."""

    def __init__(self, comm: MPI.Comm, directory: str, name: str):
        self.comm = comm
        self.path = os.path.join(directory, f"{name}_history.csv")
        self._fh = None
        self._writer = None
        self._keys: Optional[List[str]] = None
        if comm.rank == 0:
            os.makedirs(directory, exist_ok=True)
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
               camera: Optional[Sequence] = None, window_size=(1200, 900),
               show_edges: bool = True, clim=None):
    """Render the mesh (coloured by a cell field) offscreen to a PNG. Collective; rank 0 writes.

    Args:
        msh: the dolfinx mesh (current geometry).
        path: PNG file.
        cell_values: per-cell values (local cells, owned first) to colour by.
        extra_meshes: pyvista meshes (e.g. tools) drawn in grey.
        camera: pyvista camera position, or None for an isometric view.
    Returns:
        True on rank 0 if the picture was written (False if pyvista is unavailable).
    """
    data = gather_mesh_data(msh, cell_values)
    if msh.comm.rank != 0:
        return False
    try:
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        import pyvista
    except ImportError:  # pragma: no cover
        log.warning("pyvista is not installed: no picture %s", path)
        return False
    topo, ctypes, pts, vals = data
    if pts.shape[1] == 2:
        pts = np.c_[pts, np.zeros(len(pts))]
    grid = pyvista.UnstructuredGrid(topo, ctypes, pts)
    pyvista.OFF_SCREEN = True
    pl = pyvista.Plotter(off_screen=True, window_size=list(window_size))
    if vals is not None:
        grid.cell_data[scalar_name] = vals
        pl.add_mesh(grid, scalars=scalar_name, show_edges=show_edges, cmap="viridis", clim=clim,
                    scalar_bar_args={"title": scalar_name})
    else:
        pl.add_mesh(grid, show_edges=show_edges, color="lightsteelblue")
    for m in extra_meshes:
        pl.add_mesh(m, color="lightgrey", opacity=0.5)
    if title:
        pl.add_text(title, font_size=12)
    if camera is not None:
        pl.camera_position = camera
    else:
        pl.view_isometric()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    pl.screenshot(path)
    pl.close()
    return True
