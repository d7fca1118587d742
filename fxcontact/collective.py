"""Set-up checks made by every rank together, so that a set-up error never hangs under MPI.

During a run, an error on one rank is raised on every rank (contributors, outputs,
checkpoints). The set-up is the user's script: a call made on one rank only, a tool that is
``None`` on one rank, a dt that differs between ranks would leave one rank raising and the other
waiting forever in the next collective operation. Every set-up call of fxcontact that takes part
in a collective operation (``Simulation``, ``facets``, ``add_velocity_bc``, ``ContactBoundary``,
``NodalContact``, ``run``, ``step`` and the set-up before the first increment) therefore starts
with :func:`check_together`: one ``allgather`` of the call's name, of the error this rank met in
its local checks, and of the values that must agree between ranks. Then every rank raises the
same error, saying which rank failed, which value differs (and on which ranks), or that the ranks
are in different calls.

During a run, :func:`check_decision` checks the inputs of a choice that every rank must make
alike (global values by construction, e.g. a Krylov solve's iteration count) with one small
allreduce, and raises :class:`RanksDisagree` on every rank when they differ: a bug, which would
otherwise hang the run in its next collective operations.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import inspect
import math
from contextlib import contextmanager
from typing import Optional

import numpy as np
from mpi4py import MPI

from fxcontact.tools.base import Tool

__all__ = ["check_together", "together", "digest", "describe", "digest_parameters",
           "check_decision", "RanksDisagree"]

#: values longer than this are shown shortened (around their first difference) in messages
_SHOWN = 120


def _error_class(module: str, qualname: str):
    """The class of an exception raised on another rank (RuntimeError if not importable)."""
    try:
        obj = importlib.import_module(module)
        for part in qualname.split("."):
            obj = getattr(obj, part)
        if isinstance(obj, type) and issubclass(obj, Exception):
            return obj
    except (ImportError, AttributeError):
        pass
    return RuntimeError


def _make_error(cls, message: str) -> Exception:
    try:
        return cls(message)
    except Exception:   # a class whose constructor takes other arguments
        return RuntimeError(message)


def _ranks(ranks) -> str:
    ranks = list(ranks)
    return f"rank {ranks[0]}" if len(ranks) == 1 else f"ranks {ranks}"


def check_together(comm, where: str, error: Optional[BaseException] = None, share=None,
                   **agree):
    """One collective check of a set-up call (every rank calls it at the same point).

    Args:
        comm: the communicator of the call.
        where: the call, as the user wrote it (``"Simulation.run()"``): ranks in different
            calls raise a ValueError naming both.
        error: the exception this rank met in the call's local checks, or None. If some rank
            has one, every rank raises it (the same class and message; the ranks that failed
            are named when not all did).
        share: a value gathered from every rank and returned (list by rank), so that a call
            needs no other collective operation at its start.
        agree: values that must be the same on every rank (numbers, strings, tuples; use
            :func:`digest` for large ones): a ValueError names the first one that differs and
            its value on each rank.

    Returns:
        The list of the ranks' ``share`` values.
    """
    err = None if error is None else (type(error).__module__, type(error).__qualname__,
                                      str(error))
    items = {k: v if isinstance(v, (bool, int, float, type(None))) else str(v)
             for k, v in agree.items()}
    got = comm.allgather((where, err, items, share))
    wheres = [g[0] for g in got]
    if len(set(wheres)) > 1:
        by = {}
        for r, w in enumerate(wheres):
            by.setdefault(w, []).append(r)
        calls = "; ".join(f"{_ranks(rs)} in {w}" for w, rs in by.items())
        raise ValueError(f"the set-up differs between ranks: {calls}. Every rank must make the "
                         f"same fxcontact calls, in the same order (a call made under "
                         f"'if rank == 0' or an error caught on one rank only?)") from error
    failed = [r for r, g in enumerate(got) if g[1] is not None]
    if failed:
        if error is not None and len(failed) == comm.size:
            raise error
        module, qualname, msg = got[failed[0]][1]
        if len(failed) < comm.size:
            msg = f"{msg} [raised on {_ranks(failed)} only: the set-up differs between ranks]"
        raise _make_error(_error_class(module, qualname), msg) from error
    keys = list(dict.fromkeys(k for g in got for k in g[2]))   # rank 0's order first
    for key in keys:
        vals = [g[2].get(key) for g in got]
        if any(v != vals[0] for v in vals):
            by = {}
            for r, v in enumerate(vals):
                by.setdefault(v, []).append(r)
            at = _first_difference([str(v) for v in by])
            shown = "; ".join(f"{_ranks(rs)}: {_excerpt(v, at)}" for v, rs in by.items())
            raise ValueError(f"{where}: {key} differs between ranks ({shown}). The set-up must "
                             f"be the same on every rank")
    return [g[3] for g in got]


class RanksDisagree(RuntimeError):
    """The ranks took different decisions during a run (a bug: the run would hang in its next
    collective operations); raised on every rank by :func:`check_decision`, never retried."""


def check_decision(comm, where: str, **values):
    """During a run: raise :class:`RanksDisagree` on every rank if the numbers ``values`` (the
    inputs of a choice that every rank must make alike, global by construction) differ between
    ranks, naming them with their extreme values; one allreduce of 2n numbers (every rank
    calls it at the same point)."""
    if comm.size == 1:
        return
    vals = np.array([float(v) for v in values.values()])
    ext = np.empty(2 * len(vals))
    comm.Allreduce(np.concatenate([vals, -vals]), ext, op=MPI.MIN)   # (buffers: elementwise)
    lo, hi = ext[:len(vals)], -ext[len(vals):]
    if np.array_equal(lo, hi):
        return
    diff = ", ".join(f"{k} from {a:g} to {b:g}" for k, a, b in zip(values, lo, hi) if a != b)
    raise RanksDisagree(f"{where}: the ranks disagree ({diff} over the ranks): a rank-local "
                        f"value reached a choice that every rank must make alike, and the run "
                        f"would hang; please report it")


@contextmanager
def together(comm, where: str, **agree):
    """``with together(comm, "f()", ...):`` local checks of a set-up call; on leaving, an error
    of any rank is raised on every rank (:func:`check_together`). The block must not contain
    a collective operation."""
    error = None
    try:
        yield
    except Exception as e:   # raised on every rank by check_together
        error = e
    check_together(comm, where, error, **agree)


def _first_difference(texts) -> int:
    """The first position where the texts differ."""
    n = min(len(t) for t in texts)
    return next((i for i in range(n) if len({t[i] for t in texts}) > 1), n)


def _excerpt(value, at: int) -> str:
    """A value as shown in a message: whole if short, else around the position ``at``."""
    text = str(value)
    if len(text) <= _SHOWN:
        return text
    lo = max(at - 40, 0)
    return ("..." if lo else "") + text[lo:lo + 90] + ("..." if lo + 90 < len(text) else "")


def _is_function(obj) -> bool:
    return inspect.isroutine(obj) or type(obj).__name__.endswith("Dispatcher")   # numba


def _walk(obj, depth: float, text: bool):
    """The one traversal behind :func:`describe` (``text=False``: plain JSON values) and
    :func:`digest` (``text=True``: one string). Numbers, strings, arrays, sequences and dicts
    are walked alike. They differ where their uses differ:

    * floats: in full (``describe``) or to 12 digits (``digest``: not the last bits, which
      depend on the order of a reduction between ranks);
    * arrays: as lists (``describe``) or by shape and hash (``digest``: one short string to
      gather);
    * objects: ``describe`` (a checkpoint's set-up signature, compared with a later run) takes a
      dataclass's fields and any other object by its type only (its attributes may hold the
      run's state, e.g. the rates a :class:`~fxcontact.idle.ControlledMotion` was set to), a
      function by its name; ``digest`` (compared between ranks in one run) takes the public
      attributes of any object, nested up to ``depth``, and leaves functions out.
    """
    if not text and dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {"type": type(obj).__name__}
        out.update({f.name: _walk(getattr(obj, f.name), depth - 1, text)
                    for f in dataclasses.fields(obj) if f.repr})
        return out
    if isinstance(obj, (float, np.floating)):
        return f"{float(obj):.12g}" if text else float(obj)
    if obj is None or isinstance(obj, (bool, int, str, np.integer)):
        value = obj.item() if isinstance(obj, np.generic) else obj
        return repr(value) if text else value
    if isinstance(obj, np.ndarray):
        if not text:
            return _walk(obj.tolist(), depth, text)
        a = np.ascontiguousarray(obj)
        return f"array{a.shape}:{hashlib.sha1(a.tobytes()).hexdigest()[:10]}"
    if depth <= 0:
        return type(obj).__name__
    if isinstance(obj, (list, tuple)):
        items = [_walk(o, depth - 1, text) for o in obj]
        return "[" + ", ".join(items) + "]" if text else items
    if isinstance(obj, dict):
        if not text:
            return {str(k): _walk(v, depth - 1, text) for k, v in obj.items()}
        return "{" + ", ".join(f"{k}: {_walk(v, depth - 1, text)}"
                               for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))) + "}"
    if not text:
        if callable(obj):
            return f"function {getattr(obj, '__qualname__', type(obj).__name__)}"
        return type(obj).__name__
    if _is_function(obj):
        return type(obj).__name__
    attrs = {k: v for k, v in sorted(getattr(obj, "__dict__", {}).items())
             if not k.startswith("_") and not _is_function(v)}
    return type(obj).__name__ + "(" + ", ".join(f"{k}={_walk(v, depth - 1, text)}"
                                                for k, v in attrs.items()) + ")"


def describe(obj):
    """Plain (JSON) description of a set-up object for the set-up signature of a checkpoint:
    the fields of a dataclass (materials, friction laws, motions) with its type, numbers,
    strings, sequences; a function by its name (its code is not compared); any other object by
    its type."""
    return _walk(obj, math.inf, text=False)


def digest(obj, depth: int = 3) -> str:
    """A description of ``obj`` that is the same on every rank for the same parameters:
    numbers (floats to 12 digits), strings, arrays (by a hash), sequences, dicts and the
    public attributes of objects (nested up to ``depth``); callables and private attributes
    (caches, rank-local data) are left out."""
    return _walk(obj, depth, text=True)


def digest_parameters(obj) -> str:
    """A contributor, controller or kinematics as compared between ranks: its type, its scalar
    parameters and its tools (:func:`digest`), not its rank-local data."""
    if not hasattr(obj, "__dict__"):
        return type(obj).__name__
    out = {}
    for k, v in sorted(vars(obj).items()):
        if k.startswith("_"):
            continue
        if v is None or isinstance(v, (bool, int, float, str, np.integer, np.floating)):
            out[k] = v
        elif isinstance(v, Tool) or (isinstance(v, (list, tuple)) and v
                                     and all(isinstance(t, Tool) for t in v)):
            out[k] = v
    return type(obj).__name__ + digest(out, depth=6)
