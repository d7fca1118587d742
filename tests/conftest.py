import gc
import os

import pytest
from mpi4py import MPI

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


@pytest.fixture(autouse=True)
def _collective_cleanup():
    """Run collective destructors together on every rank after each test."""
    yield
    if MPI.COMM_WORLD.size > 1:
        gc.collect()
        MPI.COMM_WORLD.barrier()


def pytest_configure(config):
    config.addinivalue_line("markers", "serial: only meaningful on one rank")


def pytest_collection_modifyitems(config, items):
    if MPI.COMM_WORLD.size > 1:
        skip = pytest.mark.skip(reason="serial-only test")
        for item in items:
            if "serial" in item.keywords:
                item.add_marker(skip)


@pytest.fixture(autouse=True, scope="module")
def _release_solver_options():
    """PETSc's options database holds at most 512 entries, and every solver prefix writes about
    30: after each test module, remove the options that solvers wrote under the modules' own
    prefixes (the library's default prefixes are overwritten in place, not added)."""
    yield
    from petsc4py import PETSc

    from fxcontact.newton import solver
    opts = PETSc.Options()
    for prefix in [p for p in solver._WRITTEN_OPTIONS if not p.startswith("fxc_")]:
        for key in solver._WRITTEN_OPTIONS.pop(prefix):
            opts.delValue(prefix + key)
