"""Every dolfinx-version-specific call of fxcontact lives here (tested with dolfinx 0.5.2).

When the stack moves to a newer dolfinx, this is the module to change: names such as
``form_compiler_params`` (→ ``form_compiler_options``), ``FunctionSpace`` (→ ``functionspace``),
``create_vtk_mesh`` (→ ``vtk_mesh``), ``dofmap.list.array`` (→ 2D array) changed after 0.5.
"""

from __future__ import annotations

import functools
import sys

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.jit
import dolfinx.la
import dolfinx.mesh
import dolfinx.plot
import numpy as np

__all__ = [
    "DOLFINX_VERSION", "form", "function_space", "collapse", "dofmap_array", "cell_dofs",
    "entities_to_geometry", "vtk_mesh", "interpolation_points", "locate_dofs_topological",
    "cell_vertices", "model_to_mesh", "num_owned", "XDMFFile", "VTKFile", "jit_params",
    "JIT_EXTRA_COMPILE_ARGS", "cell_kernel", "pack_cell_coefficients", "pack_constants",
    "geometry_dofmap", "ghosted_vector",
]

DOLFINX_VERSION = dolfinx.__version__

XDMFFile = dolfinx.io.XDMFFile
VTKFile = dolfinx.io.VTKFile


#: C compiler flags appended to dolfinx's JIT flags (``cffi_extra_compile_args``: the
#: default ``-O2 -g0`` or a user's ``dolfinx_jit_parameters.json``) for fxcontact's forms.
#: ``-fno-math-errno``: ``sqrt`` and ``pow`` no longer set ``errno``, so GCC may inline ``sqrt``
#: and merge repeated ``pow`` calls with the same arguments — the FFCx Norton–Hoff tangent
#: calls ``pow(z, m-1)`` / ``pow(z, m-3)`` 36 times per quadrature point, which GCC cannot
#: merge otherwise. The same floating-point operations run, so the element tensors are
#: bitwise identical (no ``-march=native``: FMA contraction would change the round-off, and
#: the JIT cache, keyed by the flags, may be shared between machines). ``[]``: dolfinx's flags.
#: The flags are part of FFCx's cache key (a changed list compiles new modules).
JIT_EXTRA_COMPILE_ARGS = ["-fno-math-errno"]


def jit_params(user=None) -> dict:
    """dolfinx ``jit_params`` for fxcontact's forms: ``user``'s, and unless they set
    ``cffi_extra_compile_args`` themselves, dolfinx's compiler flags plus
    :data:`JIT_EXTRA_COMPILE_ARGS`."""
    p = dict(user or {})
    if "cffi_extra_compile_args" not in p and JIT_EXTRA_COMPILE_ARGS:
        base = list(dolfinx.jit.get_parameters()["cffi_extra_compile_args"])
        p["cffi_extra_compile_args"] = base + [a for a in JIT_EXTRA_COMPILE_ARGS
                                               if a not in base]
    return p


def form(f, jit_params=None):
    """Compile a UFL form (or nested list of forms) with :func:`jit_params`."""
    fcp = {}
    return dolfinx.fem.form(f, form_compiler_params=fcp, jit_params=_jit(jit_params))


_jit = jit_params


def expression(expr, points):
    """Compile a UFL expression evaluated at reference points."""
    return dolfinx.fem.Expression(expr, points)


def function_space(msh, element):
    """Function space from a UFL element or an ("family", degree) tuple."""
    return dolfinx.fem.FunctionSpace(msh, element)


def vector_function_space(msh, family: str, degree: int):
    return dolfinx.fem.VectorFunctionSpace(msh, (family, degree))


def collapse(V):
    """Collapse a sub-space: returns (collapsed space, map collapsed dof -> parent dof)."""
    Vc, dofs = V.collapse()
    return Vc, np.asarray(dofs, dtype=np.int32)


def dofmap_array(V) -> np.ndarray:
    """The cell→dof list of ``V`` as a 2D (num_cells, dofs_per_cell) array."""
    ncells = V.mesh.topology.index_map(V.mesh.topology.dim).size_local \
        + V.mesh.topology.index_map(V.mesh.topology.dim).num_ghosts
    return np.asarray(V.dofmap.list.array, dtype=np.int32).reshape(ncells, -1)


def cell_dofs(V, cell: int) -> np.ndarray:
    return np.asarray(V.dofmap.cell_dofs(cell), dtype=np.int32)


def cell_vertices(msh) -> np.ndarray:
    """(num_cells, vertices_per_cell) cell→vertex connectivity (local indices)."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    c2v = msh.topology.connectivity(tdim, 0)
    ncells = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    return np.asarray(c2v.array, dtype=np.int32).reshape(ncells, -1)


def entities_to_geometry(msh, dim: int, entities) -> np.ndarray:
    """Geometry node indices of mesh entities (vertices: one node each)."""
    return np.asarray(dolfinx.cpp.mesh.entities_to_geometry(
        msh._mesh, dim, np.asarray(entities, dtype=np.int32), False), dtype=np.int32)


def vtk_mesh(msh):
    """(topology, cell_types, geometry) of the owned cells, for pyvista."""
    return dolfinx.plot.create_vtk_mesh(msh)


def interpolation_points(V) -> np.ndarray:
    ip = V.element.interpolation_points
    return ip() if callable(ip) else ip


def locate_dofs_topological(V, dim: int, entities):
    return dolfinx.fem.locate_dofs_topological(V, dim, entities)


def num_owned(index_map) -> int:
    return index_map.size_local


def model_to_mesh(model, comm, rank: int = 0, gdim: int = 3):
    """gmsh model → (mesh, cell_tags, facet_tags) (``read_from_msh`` is broken in 0.5.2)."""
    from dolfinx.io import gmshio  # here, not at the top: it imports gmsh (see import_gmsh)
    return gmshio.model_to_mesh(model, comm, rank, gdim=gdim)


def cell_kernel(form, name: str = "form"):
    """The FFCx ``tabulate_tensor`` (float64) of the only cell integral of a compiled form, a
    cffi function pointer ``(A, w, c, coordinate_dofs, entity_local_index, permutation)``.
    ValueError unless the form has exactly one integral, over all the cells, without
    permutation data."""
    ufcx = form.ufcx_form
    cell = int(dolfinx.fem.IntegralType.cell)
    others = [t for t in form.integral_types if t != dolfinx.fem.IntegralType.cell]
    ids = [ufcx.integral_ids(cell)[i] for i in range(ufcx.num_integrals(cell))]
    if others or ids != [-1] or form.needs_facet_permutations:
        raise ValueError(f"{name}: the element condensation needs a form of cell integrals over "
                         f"the whole mesh only (got {sorted(str(t) for t in others)} integrals "
                         f"and cell subdomains {ids}); assemble facet or subdomain terms apart")
    return ufcx.integrals(cell)[0].tabulate_tensor_float64


def pack_cell_coefficients(form) -> np.ndarray:
    """(num_cells, stride) packed coefficients of the whole-mesh cell integral of a form."""
    packed = dolfinx.cpp.fem.pack_coefficients(form)
    arr = packed[(dolfinx.fem.IntegralType.cell, -1)]
    if arr.size == 0:   # a form without coefficients: one (unread) zero per cell
        msh = form.mesh
        imap = msh.topology.index_map(msh.topology.dim)
        return np.zeros((imap.size_local + imap.num_ghosts, 1))
    return np.ascontiguousarray(arr)


def pack_constants(form) -> np.ndarray:
    """The packed constants of a compiled form."""
    return np.ascontiguousarray(dolfinx.cpp.fem.pack_constants(form))


def geometry_dofmap(msh) -> np.ndarray:
    """(num_cells, nodes per cell) geometry nodes of each cell."""
    tdim = msh.topology.dim
    imap = msh.topology.index_map(tdim)
    return np.asarray(msh.geometry.dofmap.array, dtype=np.int32).reshape(
        imap.size_local + imap.num_ghosts, -1)


def ghosted_vector(V):
    """A ghosted PETSc vector of the layout of the function space ``V``."""
    return dolfinx.la.create_petsc_vector(V.dofmap.index_map, V.dofmap.index_map_bs)


# -- gmsh -----------------------------------------------------------------------------------
# gmsh 4.8 (Debian 12) has no ``gmsh.isInitialized``, and any other call of its API before
# ``gmsh.initialize`` is undefined: it usually raises, but can also end the process with exit
# status 1 and no message (seen in 4 of 76 concurrent runs of a demo). So fxcontact
# never probes gmsh with a call: it follows ``gmsh.initialize`` / ``gmsh.finalize`` itself.

def import_gmsh():
    """The ``gmsh`` module, with its initialisation followed (see :func:`gmsh_initialized`)."""
    fresh = "gmsh" not in sys.modules
    import gmsh  # here, not at the top: whether this first import initialises gmsh matters
    if not hasattr(gmsh, "isInitialized") and not hasattr(gmsh, "_fxcontact_state"):
        _follow_gmsh(gmsh, False if fresh else None)
    return gmsh


def _follow_gmsh(gmsh, state):
    init, fin = gmsh.initialize, gmsh.finalize

    @functools.wraps(init)
    def initialize(*args, **kwargs):
        init(*args, **kwargs)
        gmsh._fxcontact_state[0] = True

    @functools.wraps(fin)
    def finalize(*args, **kwargs):
        try:
            fin(*args, **kwargs)
        finally:
            gmsh._fxcontact_state[0] = False

    gmsh._fxcontact_state = [state]
    gmsh.initialize, gmsh.finalize = initialize, finalize


def gmsh_initialized(gmsh):
    """Whether gmsh is initialised: True, False, or None where it cannot be told (gmsh 4.8
    imported and possibly initialised before fxcontact followed it; then
    ``gmsh.initialize`` is safe to call and does nothing if it was)."""
    if hasattr(gmsh, "isInitialized"):
        return bool(gmsh.isInitialized())
    state = getattr(gmsh, "_fxcontact_state", None)
    return None if state is None else state[0]
