"""Checkpoints of a :class:`~fxcontact.simulation.Simulation`: write, find, read and map back.

A checkpoint is a directory ``<output_dir>/checkpoints/<name>_<increment>/`` holding

* ``manifest.json`` (rank 0): format and package version, time, increment, the step-size state,
  the history rows, a fingerprint of the initial mesh and of the set-up (space, contributors),
  the contributors' scalar state, and the state of the controllers (``add_controller``: type
  and ``checkpoint_state()``, e.g. the rates a ring mill has set so far) and of the kinematics;
* ``rank<r>.npz`` (one per rank): the owned values of the solution, the accumulated strain, the
  geometry, the displacement and the contributors' per-vertex state, each **keyed by global
  numbers that do not depend on the partition**: a geometry node by its index in the mesh input
  (``geometry.input_global_indices``), a dof by (sub-space, dof of the entity, sorted input
  indices of the vertices of its entity). A resumed run maps every value back by its key, so it
  may run on another partition or another number of ranks.

The directory is written under a temporary name and renamed once complete (rename is atomic on
one file system): a run killed while writing leaves a ``*.tmp`` directory that is ignored, never
a corrupt latest checkpoint.

Contributors (contact, springs, your own) save their state through two optional methods:
``checkpoint_state() -> dict`` and ``restore_state(dict)``. The values of the dict may be
JSON-compatible numbers/strings/lists, numpy arrays that are the same on every rank, or
:class:`PerVertex` data on (owned) local mesh vertices; :meth:`restore_state` receives the same
keys, a :class:`PerVertex` entry coming back as a :class:`VertexLookup` whose
``at(local_vertices)`` gives the values on the resumed partition.
"""

from __future__ import annotations

import json
import logging
import os
import re
import shutil
import dataclasses
import zipfile
import zlib
from dataclasses import dataclass
from typing import Dict, List, Optional

import numpy as np
from mpi4py import MPI

from fxcontact import compat

__all__ = ["CheckpointError", "PerVertex", "VertexLookup", "FORMAT_VERSION", "latest_checkpoint",
           "list_checkpoints", "mesh_fingerprint", "describe", "signature_differences"]

log = logging.getLogger(__name__)

#: version of the checkpoint layout; a checkpoint of another version is refused
FORMAT_VERSION = 1

_DIR_RE = re.compile(r"^(?P<name>.+)_(?P<inc>\d{6,})$")


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
    import basix
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


def _as_records(keys: np.ndarray) -> np.ndarray:
    keys = np.ascontiguousarray(keys, dtype=np.int64)
    dt = np.dtype([(f"k{i}", np.int64) for i in range(keys.shape[1])])
    return keys.view(dt).reshape(-1)


class KeyTable:
    """Sorted (key → value) table of one saved field, gathered from every rank's file."""

    def __init__(self, keys: np.ndarray, values: np.ndarray):
        rec = _as_records(keys)
        order = np.argsort(rec, kind="stable")
        self.keys = rec[order]
        self.values = values[order]

    def lookup(self, keys: np.ndarray, what: str) -> np.ndarray:
        rec = _as_records(keys)
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


# ------------------------------------------------------------------------------ set-up signature
def describe(obj):
    """Plain (JSON) description of a set-up object for the set-up signature of a checkpoint:
    the fields of a dataclass (materials, friction laws, motions) with its type, numbers,
    strings, sequences; a function by its name (its code is not compared)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {"type": type(obj).__name__}
        out.update({f.name: describe(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                    if f.repr})
        return out
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return describe(obj.tolist())
    if isinstance(obj, (list, tuple)):
        return [describe(v) for v in obj]
    if isinstance(obj, dict):
        return {str(k): describe(v) for k, v in obj.items()}
    if callable(obj):
        return f"function {getattr(obj, '__qualname__', type(obj).__name__)}"
    return type(obj).__name__


def _flatten(value, prefix: str, out: dict):
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(v, f"{prefix}.{k}" if prefix else str(k), out)
    elif isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
        for i, v in enumerate(value):
            _flatten(v, f"{prefix}[{i}]", out)
    else:
        out[prefix] = value
    return out


def signature_differences(saved: dict, mine: dict) -> List[str]:
    """``["material.K: 50.0 in the checkpoint, 60.0 in this run", …]``: the parameters in
    which two set-up signatures differ (both as read back from JSON)."""
    a, b = _flatten(saved, "", {}), _flatten(mine, "", {})
    return [f"{k}: {a.get(k, 'not set')!r} in the checkpoint, {b.get(k, 'not set')!r} in this "
            f"run" for k in sorted(set(a) | set(b), key=lambda k: (k not in b, k))
            if a.get(k, "not set") != b.get(k, "not set")]


# ------------------------------------------------------------------------------ files
def list_checkpoints(directory: str, name: Optional[str] = None) -> List[str]:
    """Complete checkpoint directories in ``directory`` (of the run ``name``), oldest first."""
    if not os.path.isdir(directory):
        return []
    found = []
    for d in os.listdir(directory):
        m = _DIR_RE.match(d)
        if m is None or (name is not None and m.group("name") != name):
            continue
        p = os.path.join(directory, d)
        if os.path.isfile(os.path.join(p, "manifest.json")):
            found.append((int(m.group("inc")), p))
    return [p for _, p in sorted(found)]


def latest_checkpoint(directory: str, name: Optional[str] = None) -> Optional[str]:
    """The newest complete checkpoint in ``directory`` (of the run ``name``), or None."""
    ckpts = list_checkpoints(directory, name)
    return ckpts[-1] if ckpts else None


def _json_default(o):
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def write(comm: MPI.Comm, path: str, manifest: dict, arrays: Dict[str, np.ndarray]):
    """Write a checkpoint directory atomically (collective).

    Every rank writes ``rank<r>.npz`` into ``path + ".tmp"``; rank 0 then writes the manifest
    and renames the directory. An error on any rank is raised on every rank.
    """
    tmp = path + ".tmp"
    err = None
    if comm.rank == 0:
        try:
            if os.path.isdir(tmp):
                shutil.rmtree(tmp)
            os.makedirs(tmp)
        except OSError as e:
            err = str(e)
    err = comm.bcast(err, root=0)
    if err:
        raise OSError(f"cannot write checkpoint {path}: {err}")
    try:
        fn = os.path.join(tmp, f"rank{comm.rank}.npz")
        with open(fn, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as e:
        err = str(e)
    errs = [e for e in comm.allgather(err) if e]
    if errs:
        raise OSError(f"cannot write checkpoint {path}: {errs[0]}")
    if comm.rank == 0:
        try:
            manifest = dict(manifest, nranks=comm.size)
            with open(os.path.join(tmp, "manifest.json"), "w") as fh:
                json.dump(manifest, fh, default=_json_default)
                fh.flush()
                os.fsync(fh.fileno())
            old = path + ".old"
            if os.path.isdir(path):   # an older checkpoint of the same increment
                if os.path.isdir(old):
                    shutil.rmtree(old)
                os.rename(path, old)
            os.rename(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        except OSError as e:
            err = str(e)
    err = comm.bcast(err, root=0)
    if err:
        raise OSError(f"cannot write checkpoint {path}: {err}")


def read_manifest(path: str) -> dict:
    fn = os.path.join(path, "manifest.json")
    if not os.path.isfile(fn):
        raise CheckpointError(f"{path} is not a complete checkpoint (no manifest.json)")
    try:
        with open(fn) as fh:
            return json.load(fh)
    except (OSError, ValueError) as e:
        raise CheckpointError(f"checkpoint {path} is corrupted: cannot read its manifest "
                              f"{fn}: {e}") from None


#: what reading a damaged checkpoint file raises (a truncated or altered zip/npy/json)
_DAMAGED = (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error)


def read_arrays(path: str, nranks: int) -> Dict[str, np.ndarray]:
    """Every rank file of a checkpoint, concatenated per array name."""
    parts: Dict[str, list] = {}
    for r in range(nranks):
        fn = os.path.join(path, f"rank{r}.npz")
        if not os.path.isfile(fn):
            raise CheckpointError(f"checkpoint {path} is incomplete: {os.path.basename(fn)} "
                                  f"is missing (written by {nranks} ranks)")
        try:   # every array is read in full: zipfile checks its CRC-32
            with np.load(fn) as z:
                for k in z.files:
                    parts.setdefault(k, []).append(z[k])
        except _DAMAGED as e:
            raise CheckpointError(f"checkpoint {path} is corrupted ({os.path.basename(fn)}: "
                                  f"{type(e).__name__}: {e})") from None
    return {k: np.concatenate(v) for k, v in parts.items()}


def damage(path: str) -> Optional[str]:
    """Why the checkpoint ``path`` cannot be read (a missing, truncated or altered file), or
    None if its manifest and every array of its rank files read back intact (the arrays are
    read in full, so that zipfile checks their CRC-32)."""
    try:
        man = read_manifest(path)
        read_arrays(path, int(man["nranks"]))
    except CheckpointError as e:
        return str(e)
    except (KeyError, TypeError, ValueError) as e:
        return f"checkpoint {path} has a damaged manifest ({type(e).__name__}: {e})"
    return None


def check_intact(comm: MPI.Comm, path: str, name: Optional[str] = None):
    """Raise a CheckpointError on every rank if the checkpoint ``path`` is damaged (checked by
    rank 0): the message names the damage and the newest intact older checkpoint of the run
    ``name`` in the same directory, to resume from (``resume(path=...)``). Collective."""
    msg = None
    if comm.rank == 0:
        why = damage(path)
        if why is not None:
            older = [p for p in list_checkpoints(os.path.dirname(os.path.abspath(path)), name)
                     if _increment(p) < _increment(path)]
            intact = next((p for p in reversed(older) if damage(p) is None), None)
            msg = (f"{why}; " + (f"the newest intact checkpoint is {intact}: resume(path="
                                 f"{intact!r}) continues from there" if intact else
                                 "there is no intact older checkpoint: restart the run from "
                                 "t = 0"))
    msg = comm.bcast(msg, root=0)
    if msg:
        raise CheckpointError(msg)


def _increment(path: str) -> int:
    m = _DIR_RE.match(os.path.basename(os.path.normpath(path)))
    return int(m.group("inc")) if m else -1


def prune(comm: MPI.Comm, directory: str, name: str, keep: int):
    """Remove all but the ``keep`` newest checkpoints of ``name`` (rank 0; stale ``.tmp``
    directories too)."""
    if comm.rank != 0:
        return
    for p in list_checkpoints(directory, name)[:-keep]:
        shutil.rmtree(p, ignore_errors=True)
    for d in os.listdir(directory):
        m = _DIR_RE.match(d[:-4]) if d.endswith(".tmp") else None
        if m is not None and m.group("name") == name:
            shutil.rmtree(os.path.join(directory, d), ignore_errors=True)
