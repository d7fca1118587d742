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

import dataclasses
import json
import logging
import os
import re
import shutil
import zipfile
import zlib
from typing import Dict, List, Optional

import numpy as np
from mpi4py import MPI

from fxcontact._version import __version__
from fxcontact.collective import describe
from fxcontact.io.keys import (CheckpointError, KeyTable, PerVertex, VertexLookup, dof_keys,
                               mesh_fingerprint, vertex_keys)
from fxcontact.io.outputs import OutputError
from fxcontact.protocols import HasSetupSignature, RestoresState, SavesState
from fxcontact.remesh.remeshing import RemeshRecord, checkpoint_arrays, restore_mesh

__all__ = ["CheckpointError", "PerVertex", "VertexLookup", "FORMAT_VERSION", "latest_checkpoint",
           "list_checkpoints", "mesh_fingerprint", "describe", "signature_differences",
           "Checkpoints", "plain_state"]

log = logging.getLogger(__name__)

#: version of the checkpoint layout; a checkpoint of another version is refused
FORMAT_VERSION = 1

_DIR_RE = re.compile(r"^(?P<name>.+)_(?P<inc>\d{6,})$")


# ------------------------------------------------------------------------------ set-up signature
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


#: the marker of a controller's per-vertex state entry in a manifest (its values are arrays)
_PER_VERTEX = "__per_vertex__"


# ------------------------------------------------------------------------------ a simulation's
def plain_state(value):
    """A controller's state as plain JSON values (numpy arrays and scalars to lists/numbers)."""
    if isinstance(value, dict):
        return {str(k): plain_state(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain_state(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise ValueError(f"a controller's checkpoint_state() must hold plain numbers, strings, "
                     f"lists, dicts or numpy arrays, got {type(value).__name__}")


class Checkpoints:
    """The checkpoints of a :class:`~fxcontact.simulation.Simulation` (``checkpoint_every``,
    ``checkpoint_keep``, ``overwrite``): write, resume, and the output directory's claim.

    :meth:`Simulation.write_checkpoint <fxcontact.simulation.Simulation.write_checkpoint>` and
    :meth:`Simulation.resume <fxcontact.simulation.Simulation.resume>` are this object's
    :meth:`write` and :meth:`resume`.

    Args:
        sim: the simulation whose state (solution, strain, geometry, contributors, controllers,
            kinematics, history) is saved and restored.
    """

    def __init__(self, sim):
        self.sim = sim
        #: the manifest of the checkpoint this run was resumed from, or None
        self.resumed: Optional[dict] = None
        self._resumed_from: Optional[str] = None   # the directory of the resumed checkpoint
        #: the step a resumed run takes first (after a cut-back), or None
        self.resume_step: Optional[float] = None
        self._keys = None
        self._warned_stateless = False
        #: the fingerprint of the initial mesh, once the simulation was remeshed
        self.origin = None

    @property
    def directory(self) -> str:
        if self.sim.output_dir is None:
            raise ValueError("checkpoints need an output_dir")
        return os.path.join(self.sim.output_dir, "checkpoints")

    def path(self, increment: Optional[int] = None) -> str:
        inc = self.sim.increment if increment is None else increment
        return os.path.join(self.directory, f"{self.sim.name}_{inc:06d}")

    def write_unless_there(self):
        """A checkpoint of the current increment, unless it is written already."""
        if not os.path.isdir(self.path()):
            self.write()

    def remeshed(self):
        """Before the simulation gets a new mesh (collective): the keys of the saved arrays
        will be made again; the fingerprint of the initial mesh is kept (a checkpoint after a
        remesh is resumed from a set-up on the initial mesh)."""
        self._keys = None
        if self.origin is None:
            self.origin = mesh_fingerprint(self.sim.mesh, self.sim._x_ref)

    def _restore_mesh(self, path: str, man: dict, arrays: dict):
        """A checkpoint written after a remesh: the simulation, set up on the initial mesh,
        is bound to the checkpoint's mesh (:func:`fxcontact.remesh.remeshing.restore_mesh`)."""
        sim = self.sim
        fp = mesh_fingerprint(sim.mesh, sim._x_ref)
        if man.get("mesh_origin") != fp:
            raise CheckpointError(
                f"checkpoint {path} (written after {len(man['remeshes'])} remesh(es)) was "
                f"written for a different initial mesh ({man.get('mesh_origin')}; this mesh: "
                f"{fp}): build the same initial mesh as the checkpointed run")
        restore_mesh(sim, arrays)
        sim.remeshes = [RemeshRecord(**r) for r in man["remeshes"]]
        if sim._remeshing is not None:
            sim._remeshing.quality_after = sim.remeshes[-1].min_quality_after

    def _keys_of_arrays(self):
        """Partition-independent keys of the saved arrays (computed once)."""
        if self._keys is None:
            sim = self.sim
            sp, msh = sim.space, sim.mesh
            n = len(sim.w.x.array)
            leaves = [(k, sp.W.sub(0).sub(k)) for k in range(sp.gdim)] + [(sp.gdim, sp.W.sub(1))]
            wk = dof_keys(msh, leaves, n)
            ck = dof_keys(msh, [(0, sp.DG0)], len(sim.strain.x.array))
            xk = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[:, None]
            tdim = msh.topology.dim
            own = (sp.num_owned_dofs, msh.topology.index_map(tdim).size_local,
                   msh.geometry.index_map().size_local)
            self._keys = dict(w=wk, c=ck, x=xk, own=own, v=vertex_keys(msh))
        return self._keys

    def setup_signature(self) -> dict:
        """What a checkpoint is resumed only with (as read back from JSON): the space, the
        material and its parameters, the velocity conditions, the contributors and their
        parameters (``setup_signature()``, e.g. a contact's penalty, friction and tools)."""
        sim = self.sim
        sp = sim.space
        sig = {"element": sp.element, "gdim": sp.gdim, "dofs": sp.global_dofs(),
               "material": type(sim.material).__name__,
               "small_strain": bool(sim.material.small_strain),
               "contributors": [type(c).__name__ for c in sim.contributors],
               "material_parameters": describe(sim.material),
               "volume_correction": sim.volume_correction,
               "velocity_bcs": [describe(b.value) for b in sim._bcs],
               "contributor_parameters": [c.setup_signature()
                                          if isinstance(c, HasSetupSignature) else None
                                          for c in sim.contributors]}
        return json.loads(json.dumps(sig, default=_json_default))

    # -------------------------------------------------------------------------- write
    def write(self, path: Optional[str] = None) -> str:
        """Write a checkpoint of the current (accepted) state (collective); returns its path.
        See :meth:`Simulation.write_checkpoint
        <fxcontact.simulation.Simulation.write_checkpoint>`."""
        sim = self.sim
        sim._build()
        keys = self._keys_of_arrays()
        now, ncown, nxown = keys["own"]
        sp = sim.space
        arrays = {"w_key": keys["w"][:now], "w_prev": sim.w_prev.x.array[:now],
                  "c_key": keys["c"][:ncown], "strain": sim.strain.x.array[:ncown],
                  "strain_rate": sim.strain_rate.x.array[:ncown],
                  "x_key": keys["x"][:nxown], "x": sim.mesh.geometry.x[:nxown]}
        if sim._remeshing is not None:
            arrays["strain_ref"] = sim._remeshing.strain_ref[:ncown]
        if sim.remeshes:   # the mesh itself: the set-up of a resumed run has the initial one
            arrays.update(checkpoint_arrays(sim))
        if sim.u is not None:
            uW = np.zeros(len(sim.w.x.array))
            uW[sp.V_to_W] = sim.u.x.array
            arrays["u"] = uW[:now]
        states = []
        for i, c in enumerate(sim.contributors):
            st = {}
            if isinstance(c, SavesState):
                for k, val in c.checkpoint_state().items():
                    if isinstance(val, PerVertex):
                        arrays[f"c{i}.{k}.key"] = keys["v"][np.asarray(val.vertices)][:, None]
                        arrays[f"c{i}.{k}.val"] = np.asarray(val.values)
                        st[k] = {"per_vertex": True}
                    else:
                        st[k] = {"value": val.tolist() if isinstance(val, np.ndarray) else val,
                                 "array": isinstance(val, np.ndarray)}
            elif not self._warned_stateless:
                log.warning("contributor %s has no checkpoint_state(): it is assumed to keep "
                            "no state between increments", type(c).__name__)
            states.append(st)
        self._warned_stateless = True
        controllers = []
        for i, c in enumerate(sim.controllers):
            st = dict(c.checkpoint_state()) if isinstance(c, SavesState) else None
            for k, val in (st or {}).items():   # per-vertex entries: keyed arrays, as above
                if isinstance(val, PerVertex):
                    arrays[f"k{i}.{k}.key"] = keys["v"][np.asarray(val.vertices)][:, None]
                    arrays[f"k{i}.{k}.val"] = np.asarray(val.values)
                    st[k] = {_PER_VERTEX: True}
            controllers.append({"type": type(c).__name__,
                                "state": None if st is None else plain_state(st)})
        kin = sim.kinematics
        last = sim.history[-1] if sim.history else None
        manifest = {"format": FORMAT_VERSION, "fxcontact": __version__, "name": sim.name,
                    "t": sim.t, "increment": sim.increment, "history": sim.history,
                    "next_step": (2.0 * last["dt"] if last is not None and last.get("cutbacks")
                                  else None),
                    "mesh": mesh_fingerprint(sim.mesh, sim._x_ref),
                    "setup": self.setup_signature(), "contributors": states,
                    "controllers": controllers,
                    "kinematics": (plain_state(kin.checkpoint_state())
                                   if isinstance(kin, SavesState) else None),
                    "volume_initial": sim._volume_initial,
                    "remeshes": [dataclasses.asdict(r) for r in sim.remeshes],
                    "mesh_origin": self.origin}
        path = path or self.path()
        if sim.comm.rank == 0:
            os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        try:
            write(sim.comm, path, manifest, arrays)
        except OSError as e:
            prev = latest_checkpoint(os.path.dirname(os.path.abspath(path)), sim.name)
            raise OutputError(f"{e} (increment {sim.increment}, t = {sim.t:.6g}); the previous "
                              f"checkpoint {prev} is intact") from e
        if sim.output_dir is not None and path == self.path():
            prune(sim.comm, self.directory, sim.name, sim.checkpoint_keep)
        sim.comm.barrier()
        log.info("checkpoint written: %s", path)
        return path

    # -------------------------------------------------------------------------- resume
    def _check_manifest(self, path: str, man: dict):
        """CheckpointError if the checkpoint ``path`` is of another version, mesh, set of
        controllers or set-up than this simulation."""
        sim = self.sim
        if man.get("format") != FORMAT_VERSION or man.get("fxcontact") != __version__:
            raise CheckpointError(
                f"checkpoint {path} was written by another version (checkpoint format "
                f"{man.get('format')}, fxcontact {man.get('fxcontact')}; this is format "
                f"{FORMAT_VERSION}, fxcontact {__version__}): restart the run from t = 0")
        fp = mesh_fingerprint(sim.mesh, sim._x_ref)
        if man.get("mesh") != fp:
            raise CheckpointError(
                f"checkpoint {path} was written for a different mesh ({man.get('mesh')}; this "
                f"mesh: {fp}): build the same initial mesh as the checkpointed run")
        saved = [c["type"] for c in man.get("controllers", [])]
        mine = [type(c).__name__ for c in sim.controllers]
        if saved != mine:
            raise CheckpointError(f"checkpoint {path} was written with the controllers {saved}; "
                                  f"this simulation has {mine}: register the same controllers "
                                  f"(add_controller), in the same order, as the checkpointed run")
        for i, (c, e) in enumerate(zip(sim.controllers, man.get("controllers", []))):
            if e["state"] is not None and not isinstance(c, RestoresState):
                raise CheckpointError(f"checkpoint {path} holds a state for controller "
                                      f"{type(c).__name__} #{i}, which cannot restore it")
            if e["state"] is None and isinstance(c, RestoresState):
                raise CheckpointError(f"checkpoint {path} holds no state for controller "
                                      f"{type(c).__name__} #{i}")
        # after the controllers: their message is the more specific
        sig = self.setup_signature()
        if man.get("setup") != sig:
            diff = signature_differences(man.get("setup") or {}, sig)
            raise CheckpointError(f"checkpoint {path} was written for a different set-up: "
                                  f"{'; '.join(diff)}. Resume with the set-up of the "
                                  f"checkpointed run, or start a new run (another output_dir "
                                  f"or name, or overwrite=True)")

    def resume(self, path: Optional[str] = None) -> str:
        """Restore the state of a checkpoint, before the first increment (collective). See
        :meth:`Simulation.resume <fxcontact.simulation.Simulation.resume>`."""
        sim = self.sim
        if sim._built:
            raise RuntimeError("resume() must be called after the set-up and before the first "
                               "step()/run()")
        if path is None:
            path = latest_checkpoint(self.directory, sim.name)
            if path is None:
                raise CheckpointError(f"no checkpoint of run '{sim.name}' in {self.directory}")
        elif not os.path.isfile(os.path.join(path, "manifest.json")) and \
                latest_checkpoint(path) is not None:
            path = latest_checkpoint(path)
        # a truncated or altered file: refused, naming the newest intact checkpoint
        check_intact(sim.comm, path, sim.name)
        man = read_manifest(path)
        arrays = read_arrays(path, int(man["nranks"]))
        if man.get("remeshes"):
            self._restore_mesh(path, man, arrays)
        self._check_manifest(path, man)
        keys = self._keys_of_arrays()
        sp = sim.space
        tw = KeyTable(arrays["w_key"], arrays["w_prev"])
        sim.w_prev.x.array[:] = tw.lookup(keys["w"], "the solution")
        sim.w.x.array[:] = sim.w_prev.x.array
        tc = KeyTable(arrays["c_key"], np.c_[arrays["strain"], arrays["strain_rate"]])
        sc = tc.lookup(keys["c"], "the strain")
        sim.strain.x.array[:] = sc[:, 0]
        sim.strain_rate.x.array[:] = sc[:, 1]
        if sim._remeshing is not None and "strain_ref" in arrays:
            sim._remeshing.strain_ref = KeyTable(arrays["c_key"], arrays["strain_ref"]).lookup(
                keys["c"], "the strain at the last remesh")
        tx = KeyTable(arrays["x_key"], arrays["x"])
        sim.mesh.geometry.x[:] = tx.lookup(keys["x"], "the geometry")
        if sim.u is not None:
            tu = KeyTable(arrays["w_key"], arrays["u"])
            sim.u.x.array[:] = tu.lookup(keys["w"], "the displacement")[sp.V_to_W]
        for i, (c, st) in enumerate(zip(sim.contributors, man["contributors"])):
            if not st:
                continue
            if not isinstance(c, RestoresState):
                raise CheckpointError(f"checkpoint {path} holds a state for contributor "
                                      f"{type(c).__name__} #{i}, which cannot restore it")
            state = {}
            for k, e in st.items():
                if e.get("per_vertex"):
                    table = KeyTable(arrays[f"c{i}.{k}.key"], arrays[f"c{i}.{k}.val"])
                    state[k] = VertexLookup(table, keys["v"][:, None], f"{type(c).__name__}.{k}")
                else:
                    state[k] = np.asarray(e["value"]) if e.get("array") else e["value"]
            c.restore_state(state)
        for i, (c, e) in enumerate(zip(sim.controllers, man.get("controllers", []))):
            if e["state"] is not None:
                state = {k: VertexLookup(KeyTable(arrays[f"k{i}.{k}.key"],
                                                  arrays[f"k{i}.{k}.val"]), keys["v"][:, None],
                                         f"{type(c).__name__}.{k}")
                         if isinstance(v, dict) and v.get(_PER_VERTEX) else v
                         for k, v in e["state"].items()} \
                    if isinstance(e["state"], dict) else e["state"]
                try:
                    c.restore_state(state)
                except (KeyError, TypeError, ValueError) as err:
                    raise CheckpointError(f"checkpoint {path}: the state of controller "
                                          f"{type(c).__name__} #{i} does not fit this one: "
                                          f"{err}") from None
        kin = man.get("kinematics")
        if kin is not None and isinstance(sim.kinematics, RestoresState):
            sim.kinematics.restore_state(kin)
        sim.t = float(man["t"])
        sim.increment = int(man["increment"])
        sim.history = [dict(r) for r in man["history"]]
        self.resume_step = man.get("next_step")
        self.resumed = man
        self._resumed_from = os.path.dirname(os.path.abspath(path))
        sim._build()
        # the volume correction is relative to the initial volume of the body, not to the
        # volume at the checkpoint
        if man.get("volume_initial") is not None:
            sim._volume_initial = float(man["volume_initial"])
            sim._update_volume_correction()
        log.info("resumed %s from %s: t = %.6g, increment %d", sim.name, path, sim.t,
                 sim.increment)
        return path

    # -------------------------------------------------------------------------- output dir
    def before_first_outputs(self):
        """Before the outputs are first opened: a resumed run drops the later checkpoints of
        the run that was killed; a new run claims the output directory."""
        if self.resumed is not None:
            self._drop_later()
        else:
            self._claim_output_dir()

    def _claim_output_dir(self):
        """Before a new run writes anything: the checkpoints of another run of the same name in
        ``output_dir`` are refused (CheckpointError on every rank), or removed with
        ``overwrite=True``."""
        sim = self.sim
        old = list_checkpoints(self.directory, sim.name) if sim.comm.rank == 0 else None
        old = sim.comm.bcast(old, root=0)
        if not old:
            return
        if not sim.overwrite:
            raise CheckpointError(
                f"{self.directory} holds checkpoints of another run named '{sim.name}' "
                f"({', '.join(os.path.basename(p) for p in old)}): a new run would mix its outputs "
                f"and checkpoints with them. Continue that run with resume(), or start this one "
                f"in another output_dir or with another name, or pass overwrite=True to remove "
                f"them")
        log.warning("%s: overwrite=True: removing the checkpoints of the previous run %s",
                    sim.name, ", ".join(os.path.basename(p) for p in old))
        self._remove(old)

    def _drop_later(self):
        """A run resumed from a checkpoint older than the newest: the later checkpoints (of
        the run that was then killed) are removed, with a warning, as its later CSV rows and VTK
        steps are dropped; otherwise the next resume() would take one of them."""
        sim = self.sim
        if self._resumed_from != os.path.abspath(self.directory):
            return
        later = [p for p in list_checkpoints(self.directory, sim.name)
                 if int(p.rsplit("_", 1)[1]) > sim.increment] if sim.comm.rank == 0 else None
        later = sim.comm.bcast(later, root=0)
        if later:
            log.warning("%s: resumed at increment %d: removing the later checkpoints %s",
                        sim.name, sim.increment, ", ".join(os.path.basename(p) for p in later))
            self._remove(later)

    def _remove(self, paths):
        if self.sim.comm.rank == 0:
            for p in paths:
                shutil.rmtree(p, ignore_errors=True)
        self.sim.comm.barrier()
