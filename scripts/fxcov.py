"""A pytest plugin that reports which parts of fxcontact a test run executes.

``coverage`` is not part of the set-up, so this is a small line tracer limited to the package's
own files (other code is not traced, so the run is only a little slower). At the end it prints,
per module of ``fxcontact``: whether it was imported, the functions executed out of those
defined, and the lines executed out of the executable ones; then the modules never imported and
the ones whose functions never ran. Usage, from the repository's root::

    PYTHONPATH=.:scripts .venv/bin/python -m pytest -p fxcov -m "not slow" tests

``FXCOV_REPORT=<file>`` also writes the per-function detail (the functions never executed) there.
Limits: only the pytest process is traced (the demos that the tests start as subprocesses are
not); the bodies of numba-compiled kernels never run as Python, so they count as not executed
unless their numpy twin is called; lines are those of Python 3.11's code objects.
"""

from __future__ import annotations

import os
import sys
import threading

__all__ = ["pytest_terminal_summary"]

_ROOT = os.path.join(os.path.abspath(os.path.dirname(os.path.dirname(__file__))), "fxcontact")
_PREFIX = _ROOT + os.sep
_lines: dict[str, set[int]] = {}
_calls: set[tuple[str, int, str]] = set()
_decided: dict[object, bool] = {}


def _local(frame, event, arg):
    if event == "line":
        _lines[frame.f_code.co_filename].add(frame.f_lineno)
    return _local


def _global(frame, event, arg):
    code = frame.f_code
    ours = _decided.get(code)
    if ours is None:
        ours = _decided[code] = code.co_filename.startswith(_PREFIX)
    if not ours:
        return None
    _calls.add((code.co_filename, code.co_firstlineno, code.co_qualname))
    _lines.setdefault(code.co_filename, set()).add(code.co_firstlineno)
    return _local


sys.settrace(_global)
threading.settrace(_global)


def _code_objects(code):
    yield code
    for const in code.co_consts:
        if hasattr(const, "co_code"):
            yield from _code_objects(const)


def _module_name(path: str) -> str:
    rel = os.path.relpath(path, os.path.dirname(_ROOT))[:-3].replace(os.sep, ".")
    return rel[:-len(".__init__")] if rel.endswith(".__init__") else rel


def _survey():
    """Per module: (name, imported, functions run, functions, lines run, lines, unrun names)."""
    rows = []
    for folder, _, files in os.walk(_ROOT):
        for fname in sorted(files):
            if not fname.endswith(".py"):
                continue
            path = os.path.join(folder, fname)
            with open(path, encoding="utf-8") as fh:
                top = compile(fh.read(), path, "exec")
            executable, funcs = set(), []
            for code in _code_objects(top):
                executable.update(line for _, _, line in code.co_lines() if line)
                if code is not top:
                    funcs.append((code.co_firstlineno, code.co_qualname))
            ran = _lines.get(path, set()) & executable
            run_funcs = {(line, name) for (f, line, name) in _calls if f == path}
            called = [key for key in funcs if key in run_funcs]
            unrun = [q for (line, q) in funcs if (line, q) not in run_funcs]
            name = _module_name(path)
            rows.append((name, name in sys.modules, len(called), len(funcs), len(ran),
                         len(executable), unrun))
    return sorted(rows)


def pytest_terminal_summary(terminalreporter):
    sys.settrace(None)
    threading.settrace(None)
    rows = _survey()
    w = terminalreporter
    w.section("fxcontact executed (this process)")
    tot_l = tot_e = tot_f = tot_c = 0
    for name, imported, n_called, n_funcs, n_ran, n_exec, _ in rows:
        pct = 100.0 * n_ran / max(n_exec, 1)
        w.line(f"{name:45s} {'imported' if imported else 'NOT IMPORTED':12s} "
               f"functions {n_called:4d}/{n_funcs:<4d} lines {n_ran:5d}/{n_exec:<5d} {pct:5.1f}%")
        tot_l += n_ran
        tot_e += n_exec
        tot_c += n_called
        tot_f += n_funcs
    w.line(f"{'total':58s} functions {tot_c:4d}/{tot_f:<4d} lines {tot_l:5d}/{tot_e:<5d} "
           f"{100.0 * tot_l / max(tot_e, 1):5.1f}%")
    never = [r[0] for r in rows if not r[1]]
    idle = [r[0] for r in rows if r[1] and r[3] and not r[2]]
    w.line("never imported: " + (", ".join(never) or "none"))
    w.line("imported, no function executed: " + (", ".join(idle) or "none"))
    out = os.environ.get("FXCOV_REPORT")
    if out:
        with open(out, "w", encoding="utf-8") as fh:
            for name, imported, n_called, n_funcs, n_ran, n_exec, unrun in rows:
                fh.write(f"{name} imported={imported} functions={n_called}/{n_funcs} "
                         f"lines={n_ran}/{n_exec}\n")
                for q in unrun:
                    fh.write(f"    not executed: {q}\n")
