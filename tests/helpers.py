"""Shared test utilities (meshes, parallel/serial comparison)."""

import numpy as np
from mpi4py import MPI

import dolfinx


# A guard against hangs for the runs the tests start in a subprocess (a crash or a hang must not
# take the test session with it): far above what a run takes on a loaded machine, so only a hang
# reaches it. Never a measure of speed.
HANG_TIMEOUT = 1200.0


def box_mesh(comm, L=(1.0, 1.0, 1.0), n=(4, 4, 4), perturb=0.0, seed=0):
    msh = dolfinx.mesh.create_box(comm, [[0.0, 0.0, 0.0], list(L)], list(n),
                                  dolfinx.mesh.CellType.tetrahedron)
    if perturb > 0:
        x = msh.geometry.x
        h = np.array(L) / np.array(n)
        # deterministic perturbation of interior nodes (function of position: rank independent)
        inner = np.all((x[:, :3] > 1e-12) & (x[:, :3] < np.array(L) - 1e-12), axis=1)
        ph = np.sin(12.9898 * x[:, 0] + 78.233 * x[:, 1] + 37.719 * x[:, 2] + seed) * 43758.5453
        r = np.stack([np.sin(ph), np.sin(1.7 * ph), np.sin(2.3 * ph)], axis=1)
        x[inner, :3] += perturb * h * r[inner]
    return msh


class FakeBoundary:
    """Duck-typed ContactBoundary holding plain arrays (no dolfinx): n nodes with random areas,
    velocities read from a flat array."""

    def __init__(self, n, d=3, seed=0):
        rng = np.random.default_rng(seed)
        self.comm = MPI.COMM_SELF
        self.gdim = d
        self.areas = 0.5 + rng.random(n)
        self.vertices = np.arange(n)
        self.dofs = np.arange(n * d).reshape(n, d)

    def __len__(self):
        return len(self.areas)

    def velocities(self, w):
        return np.asarray(w).reshape(-1, self.gdim)

    def update_areas(self):
        pass


def gather_by_position(comm, x, values, decimals=9):
    """Gather (position, value) pairs on all ranks, unique by position, sorted."""
    xs = np.concatenate(comm.allgather(np.asarray(x)))
    vs = np.concatenate(comm.allgather(np.asarray(values)))
    key = np.round(xs, decimals)
    _, idx = np.unique(key, axis=0, return_index=True)
    order = np.lexsort(key[idx].T[::-1])
    return xs[idx][order], vs[idx][order]


def load_file(name, path):
    """Import the Python file ``path`` as a module named ``name``."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, str(path))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run_script(path, args=(), nranks=1, timeout=HANG_TIMEOUT):
    """Run a script as a user does (``python path args``, under ``mpirun -n nranks`` if
    ``nranks > 1``) in its own process group with the checkout on PYTHONPATH; kill the group
    and fail if it hangs. Returns ``(exit code, stdout + stderr)``."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    import pytest

    root = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""),
               OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OPENBLAS_NUM_THREADS="1")
    for k in list(env):  # the child is its own MPI job (also when the tests run under mpirun)
        if k.startswith(("OMPI_COMM", "PMIX_", "OMPI_MCA_ess", "OMPI_MCA_orte")):
            env.pop(k)
    env["PYTHONFAULTHANDLER"] = "1"   # a crash prints the Python stack of every thread
    cmd = [sys.executable, "-u", str(path), *map(str, args)]
    if nranks > 1:
        cmd = ["mpirun", "-n", str(nranks), "--oversubscribe"] + cmd
    p = subprocess.Popen(cmd, env=env, cwd=root, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        out, _ = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        pytest.fail(f"{path} on {nranks} rank(s) hangs (killed after {timeout} s)")
    return p.returncode, out


def shared_tmpdir(prefix):
    """A temporary directory made on rank 0 and known to every rank."""
    import tempfile

    comm = MPI.COMM_WORLD
    d = tempfile.mkdtemp(prefix=prefix) if comm.rank == 0 else None
    return comm.bcast(d, root=0)


def assert_histories_match(h_par, h_ser, keys, rtol=1e-8, scale_key="tool_force_z"):
    """Same number of increments and, per increment, the values of ``keys`` within ``rtol``
    of the reference's ``scale_key`` (the vertical tool force; at least 1)."""
    assert len(h_par) == len(h_ser)
    for a, b in zip(h_par, h_ser):
        F = max(abs(b[scale_key]), 1.0)
        for k in keys:
            assert abs(a[k] - b[k]) <= rtol * F, (k, a["time"], a[k], b[k])


def vertex_velocities_by_position(sim, comm=MPI.COMM_WORLD):
    """The P1 vertex velocities of a Simulation, gathered on every rank and ordered by the
    vertices' reference positions (compares runs whose partitions differ)."""
    sp = sim.space
    own = sp.vertex_owned
    return gather_by_position(comm, sim._x_ref[sp.vertex_geometry][own],
                              sim.w.x.array[sp.vertex_dofs[own]])[1]



def assert_newton_counts_match(a: int, b: int, bitwise: bool = False):
    """Newton iteration counts of two runs of the same problem. Runs that are bitwise equal
    (serially, the same operations) take the same count. Runs that agree only to round-off
    (another rank count, another partition, another linear solver; parallel MUMPS is not even
    reproducible from run to run) may differ by one: the convergence test is a threshold, and
    a last residual that lands on the tolerance passes or fails on round-off, which depends on
    the partition and the BLAS build. The converged values are what such tests compare."""
    if bitwise:
        assert a == b, (a, b)
    else:
        assert abs(a - b) <= 1, (a, b)


def run_readme_block(title, replacements, max_lines=40):
    """Run the python block of the README's section ``### <title>`` with ``replacements``
    (old → new, each found exactly once: an example that no longer matches fails) in a
    namespace holding ``dataclasses.replace`` as ``replace``; returns the namespace. The block
    must stay within ``max_lines`` lines."""
    import dataclasses
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    code = re.search(r"```python\n(.*?)```", text.split(f"### {title}\n", 1)[1],
                     re.S).group(1)
    assert len(code.splitlines()) <= max_lines, f"README {title}: more than {max_lines} lines"
    for old, new in replacements.items():
        assert code.count(old) == 1, f"README example {title} changed: {old!r} not found once"
        code = code.replace(old, new)
    ns = {"replace": dataclasses.replace}
    exec(compile(code, "README.md", "exec"), ns)
    return ns
