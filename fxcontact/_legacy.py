"""The module names of fxcontact 0.1 before the packages by concern, kept for one release.

``import fxcontact.solver`` (or ``from fxcontact.petsc import NodalTerms``) still works: it
gives a module that holds every name of the old module, taken from where it lives now, and
warns once with a :class:`DeprecationWarning` that names the new module. The table
:data:`MOVED` is the whole list; nothing else is redirected. New code imports the new names::

    fxcontact.petsc            -> fxcontact.newton.problem
    fxcontact.solver           -> fxcontact.newton.solver
    fxcontact.element_jacobian -> fxcontact.element.jacobian
    ...

Names that moved out of the package's top level (``fxcontact.RingCentring``, now in
:mod:`fxcontact.processes.ring_rolling`, so that ``import fxcontact`` loads no process) are in
:data:`MOVED_NAMES`, resolved by the package's ``__getattr__`` with the same warning.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings

__all__ = ["MOVED", "MOVED_NAMES", "install", "moved_name"]

#: old module -> the modules that hold its names now (the first one is named in the warning)
MOVED = {
    "fxcontact.petsc": ("fxcontact.newton.problem", "fxcontact.la"),
    "fxcontact.solver": ("fxcontact.newton.solver", "fxcontact.newton.options",
                         "fxcontact.newton.bordered"),
    "fxcontact.solver_options": ("fxcontact.newton.options",),
    "fxcontact.bordered": ("fxcontact.newton.bordered",),
    "fxcontact.prediction": ("fxcontact.newton.prediction",),
    "fxcontact.multisolve": ("fxcontact.la",),
    "fxcontact.retry": ("fxcontact.newton.retry",),
    "fxcontact.cell_kernels": ("fxcontact.element.cell",),
    "fxcontact.element_condense": ("fxcontact.element.tensors", "fxcontact.element.cell"),
    "fxcontact.element_jacobian": ("fxcontact.element.jacobian", "fxcontact.element.cell"),
    "fxcontact.condense": ("fxcontact.element.assembled", "fxcontact.la"),
    "fxcontact.dual": ("fxcontact.element.dual",),
    "fxcontact.dual_kernel": ("fxcontact.element.dual",),
    "fxcontact.forms": ("fxcontact.materials.forms",),
    "fxcontact.forming": ("fxcontact.theory.forming",),
    "fxcontact.rolling": ("fxcontact.theory.flat_rolling",),
    "fxcontact.outputs": ("fxcontact.io.outputs",),
    "fxcontact.springs": ("fxcontact.contact.springs",),
    "fxcontact.mill": ("fxcontact.idle", "fxcontact.processes.ring_rolling.mill",
                       "fxcontact.kinematics"),
    "fxcontact.cylindrical": ("fxcontact.kinematics",),
    "fxcontact.remesh.simulation": ("fxcontact.remesh.remeshing",),
    "fxcontact.remesh.boundary": ("fxcontact.remesh.surface",),
    "fxcontact.processes.ring_mill": ("fxcontact.processes.ring_rolling.mill",),
    "fxcontact.processes.ring_pictures": ("fxcontact.processes.ring_rolling.pictures",),
}

#: old top-level name of the package -> the module that holds it now
MOVED_NAMES = {
    "RingCentring": "fxcontact.processes.ring_rolling.mill",
}


def _warn(old: str, new: str, stacklevel: int = 3):
    warnings.warn(f"{old} is deprecated and will be removed in the next release: use {new}",
                  DeprecationWarning, stacklevel=stacklevel)


def _legacy_module(old: str) -> types.ModuleType:
    """A module named ``old`` holding the names of the modules that replaced it (the first
    one wins on a clash)."""
    mod = types.ModuleType(old, f"Deprecated: the names of {old}, now in "
                           f"{', '.join(MOVED[old])}.")
    for new in reversed(MOVED[old]):
        src = importlib.import_module(new)
        mod.__dict__.update({k: v for k, v in vars(src).items() if not k.startswith("__")})
    mod.__all__ = list(getattr(importlib.import_module(MOVED[old][0]), "__all__", []))
    return mod


class _Loader(importlib.abc.Loader):
    def create_module(self, spec):
        _warn(f"module {spec.name}", "module " + MOVED[spec.name][0], stacklevel=8)
        return _legacy_module(spec.name)

    def exec_module(self, module):
        pass


class _Finder(importlib.abc.MetaPathFinder):
    """Finds the old module names of :data:`MOVED` only (after every other finder)."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Loader())


def install():
    """Put the finder of the old module names at the end of ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())


def moved_name(name: str):
    """The object a former top-level name of the package stands for, with a warning
    (the package's ``__getattr__``)."""
    if name not in MOVED_NAMES:
        raise AttributeError(f"module 'fxcontact' has no attribute {name!r}")
    _warn(f"fxcontact.{name}", f"{MOVED_NAMES[name]}.{name}")
    return getattr(importlib.import_module(MOVED_NAMES[name]), name)
