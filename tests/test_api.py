"""The public API is importable from ``fxcontact`` itself, documented, and the same objects as in
the submodules."""

import importlib
import pydoc

import pytest
from mpi4py import MPI

import fxcontact as fx


def test_all_names_importable_and_documented():
    assert fx.__version__
    for name in fx.__all__:
        if name == "__version__":
            continue
        obj = getattr(fx, name)
        mod, text = fx._API[name]
        assert obj is getattr(importlib.import_module(f"fxcontact.{mod}"), name), name
        assert text.strip(), name
        assert f"* {name} ({mod}): " in fx.__doc__, name
        if callable(obj):
            assert (obj.__doc__ or "").strip(), f"{name} has no docstring"


def test_api_is_imported_explicitly():
    """Every public name is imported by ``fxcontact/__init__.py`` itself (no lazy look-up), the
    names that clash with dolfinx have their own names, the old ones are aliases."""
    import ast
    from pathlib import Path

    tree = ast.parse(Path(fx.__file__).read_text(encoding="utf-8"))
    imported = {a.asname or a.name for node in tree.body if isinstance(node, ast.ImportFrom)
                for a in node.names}
    assert set(fx._API) <= imported, set(fx._API) - imported
    assert set(fx.__all__) == {"__version__", *fx._API}
    # the only look-up: former top-level names that moved out, with a warning
    assert set(fx._legacy.MOVED_NAMES).isdisjoint(fx.__all__)
    assert fx.NonlinearProblem is fx.NodalNonlinearProblem
    assert fx.NewtonSolver is fx.ContactNewtonSolver
    assert fx.NodalNonlinearProblem.__name__ == "NodalNonlinearProblem"
    assert fx.ContactNewtonSolver.__name__ == "ContactNewtonSolver"


def test_former_names_warn_and_resolve():
    """The module names of the flat layout and the top-level names that moved out still work
    for one release, each with a DeprecationWarning that names the new place; ``import
    fxcontact`` loads no process."""
    import importlib
    import subprocess
    import sys

    if MPI.COMM_WORLD.size == 1:   # a python started inside an MPI job cannot initialise MPI
        code = ("import sys, fxcontact; "
                "print(any(m.startswith('fxcontact.processes') for m in sys.modules))")
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True)
        assert out.stdout.strip() == "False", out.stdout + out.stderr
    from fxcontact import _legacy
    for old, new in _legacy.MOVED.items():
        sys.modules.pop(old, None)
        with pytest.warns(DeprecationWarning, match=new[0].replace(".", r"\.")):
            mod = importlib.import_module(old)
        for name in getattr(importlib.import_module(new[0]), "__all__", []):
            assert getattr(mod, name) is getattr(importlib.import_module(new[0]), name)
    for name, where in _legacy.MOVED_NAMES.items():
        with pytest.warns(DeprecationWarning, match=name):
            assert getattr(fx, name) is getattr(importlib.import_module(where), name)


def test_star_import_and_help():
    ns = {}
    exec("from fxcontact import *", ns)
    assert set(fx.__all__) <= set(ns)
    text = pydoc.render_doc(fx, renderer=pydoc.plaintext)
    for name in ("Simulation", "NodalContact", "FacetedTool", "SolverOptions", "IncrementError"):
        assert f"class {name}" in text
    with pytest.raises(AttributeError, match="no attribute 'Nonexistent'"):
        fx.Nonexistent
    assert set(fx._API) <= set(dir(fx))


def test_contributors_and_controllers_satisfy_their_protocols():
    """The library's contributors are ``Contributor``s with the hooks the simulation calls;
    the bordered idle rotation's stand-in for the contact (a ``__getattr__`` proxy) declares
    the protocol's methods itself; the ring-mill controllers' optional hooks are protocols too."""
    from fxcontact import idle as mill, protocols as pr
    from fxcontact.processes.ring_rolling import RingCentring

    for cls in (fx.NodalContact, fx.NodalSprings, mill._EliminatedContact):
        assert issubclass(cls, pr.Contributor), cls
    for proto in (pr.BeginsIncrement, pr.EndsIncrement, pr.HasDiagnostics, pr.HasOutputFields,
                  pr.UpdatesOutputFields, pr.SavesState, pr.RestoresState,
                  pr.HasSetupSignature, pr.HasSummary, pr.SolverHooks):
        assert issubclass(fx.NodalContact, proto), proto
    assert issubclass(fx.IdleRotation, pr.SolvesIncrement)
    assert not issubclass(RingCentring, pr.SolvesIncrement)
    for cls in (fx.IdleRotation, RingCentring, fx.RingAxisUpdate):
        assert issubclass(cls, pr.SavesState) and issubclass(cls, pr.RestoresState), cls
    assert not isinstance(object(), pr.Contributor)
