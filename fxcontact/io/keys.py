"""Partition-independent keys of a mesh's vertices and dofs, the tables that look saved values
up by them, and a mesh's fingerprint: what a checkpoint (:mod:`fxcontact.checkpoint`) and a
remeshed run's restore (:mod:`fxcontact.remesh.remeshing`) use to find the same entity on
another partition."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict

import basix
import numpy as np
from mpi4py import MPI

from fxcontact import compat

__all__ = ["CheckpointError", "PerVertex", "VertexLookup", "KeyTable", "as_records", "dof_keys",
           "mesh_fingerprint", "vertex_keys"]


class CheckpointError(ValueError):
    """A checkpoint that cannot be used: missing, incomplete, from another version, or of
    another mesh or set-up."""


@dataclass
class PerVertex:
    """Values on local mesh vertices (owned ones; each vertex saved once over all ranks)."""

    vertices: np.ndarray
    values: np.ndarray


class VertexLookup:
    """Values saved per vertex, looked up on the vertices of the resumed partition."""

    def __init__(self, table: "KeyTable", vertex_keys: np.ndarray, what: str):
        self._table, self._vkeys, self._what = table, vertex_keys, what

    def at(self, vertices) -> np.ndarray:
        vertices = np.asarray(vertices, dtype=np.int64)
        return self._table.lookup(self._vkeys[vertices], self._what)


# ------------------------------------------------------------------------------ keys
def vertex_keys(msh) -> np.ndarray:
    """(num_local_vertices,) input index (mesh file / generator numbering) of each vertex."""
    imap = msh.topology.index_map(0)
    nv = imap.size_local + imap.num_ghosts
    nodes = compat.entities_to_geometry(msh, 0, np.arange(nv, dtype=np.int32)).ravel()
    return np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[nodes]


def _reference_entities(msh):
    name = msh.topology.cell_type.name
    return basix.topology(getattr(basix.CellType, name))


def dof_keys(msh, leaves, size: int) -> np.ndarray:
    """Partition-independent keys of the dofs of a (mixed) space.

    Args:
        leaves: ``[(label, scalar sub-space), …]`` whose dofmaps give indices of the array.
        size: length of the Function's local array.
    Returns:
        (size, tdim + 3) int64: label, dof within the entity, sorted input indices of the
        entity's vertices padded with −1 (rows of dofs no leaf touches stay −1).
    """
    tdim = msh.topology.dim
    c2v = compat.cell_vertices(msh)
    vk = vertex_keys(msh)
    ref = _reference_entities(msh)
    keys = np.full((size, tdim + 3), -1, dtype=np.int64)
    for label, S in leaves:
        layout = S.dofmap.dof_layout
        dm = compat.dofmap_array(S)
        for d in range(tdim + 1):
            for i, verts in enumerate(ref[d]):
                ent = np.sort(vk[c2v[:, verts]], axis=1)
                for j, ld in enumerate(layout.entity_dofs(d, i)):
                    dofs = dm[:, ld]
                    keys[dofs, 0] = label
                    keys[dofs, 1] = j
                    keys[dofs, 2: 2 + len(verts)] = ent
    return keys


def as_records(keys: np.ndarray) -> np.ndarray:
    """Rows of an int64 key array as one structured record each (sortable, comparable)."""
    keys = np.ascontiguousarray(keys, dtype=np.int64)
    dt = np.dtype([(f"k{i}", np.int64) for i in range(keys.shape[1])])
    return keys.view(dt).reshape(-1)


class KeyTable:
    """Sorted (key → value) table of one saved field, gathered from every rank's file."""

    def __init__(self, keys: np.ndarray, values: np.ndarray):
        rec = as_records(keys)
        order = np.argsort(rec, kind="stable")
        self.keys = rec[order]
        self.values = values[order]

    def lookup(self, keys: np.ndarray, what: str) -> np.ndarray:
        rec = as_records(keys)
        if len(self.keys) == 0:
            pos = np.zeros(len(rec), dtype=np.int64)
            ok = np.zeros(len(rec), dtype=bool)
        else:
            pos = np.searchsorted(self.keys, rec)
            pos = np.minimum(pos, len(self.keys) - 1)
            ok = self.keys[pos] == rec
        if not np.all(ok):
            raise CheckpointError(f"the checkpoint has no value of {what} for "
                                  f"{int(np.sum(~ok))} local entries (e.g. key "
                                  f"{keys[np.flatnonzero(~ok)[0]].tolist()}): it was written for "
                                  f"another mesh or another set-up")
        return self.values[pos]


# ------------------------------------------------------------------------------ fingerprint
def _mix(a: np.ndarray) -> np.ndarray:
    """splitmix64 finaliser (uint64 → uint64, wrapping arithmetic)."""
    with np.errstate(over="ignore"):
        a = a + np.uint64(0x9E3779B97F4A7C15)
        a = (a ^ (a >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        a = (a ^ (a >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return a ^ (a >> np.uint64(31))


def mesh_fingerprint(msh, x_initial: np.ndarray) -> Dict[str, object]:
    """Global cell and vertex numbers and an order-independent hash of (input index, initial
    coordinates) of the geometry nodes: the same for the same mesh on any partition."""
    comm = msh.comm
    tdim = msh.topology.dim
    gimap = msh.geometry.index_map()
    nown = gimap.size_local
    gid = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[:nown].astype(np.uint64)
    x = np.ascontiguousarray(x_initial[:nown] + 0.0)   # +0.0: no −0.0
    h = _mix(gid)
    with np.errstate(over="ignore"):
        for k in range(x.shape[1]):
            h = _mix(h ^ x[:, k].view(np.uint64))
        loc = np.array([np.sum(h, dtype=np.uint64)], dtype=np.uint64)
    tot = np.zeros(1, dtype=np.uint64)
    comm.Allreduce(loc, tot, op=MPI.SUM)
    return {"cells": int(msh.topology.index_map(tdim).size_global),
            "vertices": int(msh.topology.index_map(0).size_global),
            "gdim": int(msh.geometry.dim), "hash": f"{int(tot[0]):016x}"}
