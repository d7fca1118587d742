"""A catalogue of bad inputs across the API: each gives the stated error class with a message that
says what is wrong, on every rank, and nothing written before the error is lost or corrupted.

``CASES`` are errors at set-up; the tests after it are errors during a run (NaN from a user BC
function, Newton failure after all cut-backs, a full disk, a checkpoint that does not match, a
tool that starts buried). README.md lists every case id in its table of bad inputs (checked
below).
"""

import csv
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import dolfinx
import ufl

import fxcontact as fx
import fxcontact.element.tensors as ec
from fxcontact.checkpoint import CheckpointError, latest_checkpoint, list_checkpoints
from fxcontact.io import HistoryWriter, SeriesWriter, read_pvd
from fxcontact.simulation import IncrementError, OutputError

from helpers import HANG_TIMEOUT, box_mesh, run_script, shared_tmpdir

ROOT = Path(__file__).resolve().parents[1]
COMM = MPI.COMM_WORLD
TAGS = {"x0": 1, "y0": 2, "z0": 3, "z1": 4}


def _cube():
    """A 2×2×2 unit cube with tagged faces x0, y0, z0 (1–3) and the top z1 (4)."""
    msh = box_mesh(COMM, n=(2, 2, 2))
    loc = dolfinx.mesh.locate_entities_boundary
    where = {1: (0, 0.0), 2: (1, 0.0), 3: (2, 0.0), 4: (2, 1.0)}
    fs = {t: loc(msh, 2, (lambda c, v: (lambda x: np.isclose(x[c], v)))(c, v))
          for t, (c, v) in where.items()}
    idx = np.concatenate(list(fs.values()))
    val = np.concatenate([np.full(len(f), t, np.int32) for t, f in fs.items()])
    idx, first = np.unique(idx, return_index=True)   # an edge facet keeps one tag
    ft = dolfinx.mesh.meshtags(msh, 2, idx.astype(np.int32), val[first])
    space = fx.MixedSpace(msh)
    return dict(msh=msh, ft=ft, space=space, top=fx.ContactBoundary(space, ft, TAGS["z1"]))


@pytest.fixture(scope="module")
def ctx():
    """The cube for the set-up errors (nothing moves it)."""
    return _cube()


@pytest.fixture
def cube():
    """A fresh cube for each run (an updated-Lagrangian run moves its mesh)."""
    return _cube()


def _sim(c, **kw):
    return fx.Simulation(c["space"], fx.NortonHoff(1.0, 0.2), progress=False, **kw)


def _die(z=1.0):
    return fx.Plane((0, 0, z), (0, 0, -1), velocity=(0, 0, -0.1), name="die")


_TET = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
_TET_T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _degenerate_mesh(c):
    msh = box_mesh(COMM, n=(2, 2, 2))
    x = msh.geometry.x
    x[np.isclose(x[:, 2], 1.0), 2] = 0.5
    fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(1.0, 0.2), progress=False)


def _condensed_degenerate(c):
    msh = box_mesh(COMM, n=(2, 2, 2))
    x = msh.geometry.x
    x[np.isclose(x[:, 2], 1.0), 2] = 0.5
    space = fx.MixedSpace(msh)
    w = dolfinx.fem.Function(space.W)
    layout = ec.P1P1Layout(space.W)
    ec.CondensedAssembler(ec.NortonHoffElementTensors(layout, space, fx.NortonHoff(1.0, 0.2),
                                                      w)).assemble()


def _condensed_facet_term(c):
    space = c["space"]
    w = dolfinx.fem.Function(space.W)
    a, L = ec.norton_hoff_forms(space, fx.NortonHoff(1.0, 0.2), w)
    _, q = ufl.TestFunctions(space.W)
    ec.FFCxElementTensors(ec.P1P1Layout(space.W), a, L + q * ufl.ds)


class _OwnNortonHoff(fx.NortonHoff):
    def stress_ufl(self, eps):
        return 2.0 * super().stress_ufl(eps)


def _contact_problem(c, degree):
    """A ContactProblem (no contributor) on a vector Lagrange space of ``degree``."""
    import ufl
    V = dolfinx.fem.VectorFunctionSpace(c["msh"], ("Lagrange", degree))
    u = dolfinx.fem.Function(V)
    return fx.ContactProblem(ufl.inner(ufl.grad(u), ufl.grad(ufl.TestFunction(V))) * ufl.dx, u)


def _add_bc_after_start(c):
    s = _sim(c)
    s.add_velocity_bc(s.facets(c["ft"], TAGS["z0"]), 0.0, 2)
    s._build()
    s.add_velocity_bc(s.facets(c["ft"], TAGS["z1"]), -0.1, 2)


def _output_dir_is_a_file(c):
    d = shared_tmpdir("fxc_bad_file_")
    path = os.path.join(d, "results")
    if COMM.rank == 0:
        open(path, "w").close()
    COMM.barrier()
    try:
        _sim(c, output_dir=path)
    finally:
        COMM.barrier()
        if COMM.rank == 0:
            shutil.rmtree(d, ignore_errors=True)


def _run_time_backwards(c):
    s = _sim(c)
    s.add_velocity_bc(s.facets(c["ft"], TAGS["z0"]), 0.0, 2)
    s.t = 1.0
    s.run(0.5, 0.1)


def _tangled_mesh(c):
    """The cube's centre node moved through the top face: the cells under that face turn
    inside out and overlap their neighbours (cells of both signs)."""
    msh = box_mesh(COMM, n=(2, 2, 2))
    x = msh.geometry.x
    x[np.all(np.isclose(x, 0.5), axis=1), 2] = 1.3
    fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(1.0, 0.2), progress=False)


def _nearly_flat_mesh(c):
    """The top layer squashed to 1e-12 of its height: tiny but positive cell volumes."""
    msh = box_mesh(COMM, n=(2, 2, 2))
    x = msh.geometry.x
    x[np.isclose(x[:, 2], 1.0), 2] = 0.5 + 1e-12
    fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(1.0, 0.2), progress=False)


def _add_twice(c, what):
    s = _sim(c)
    obj = fx.NodalContact(c["top"], _die(), penalty=1.0) if what == "contributor" else object()
    add = s.add_contributor if what == "contributor" else s.add_controller
    add(obj)
    add(obj)


def _two_contacts(c, first=None, second=None, tool=None):
    """Two contacts on the top face (names ``first``/``second``, default 'contact'), the second
    against ``tool`` (default: another plane with its own name)."""
    s = _sim(c)
    kw1 = {} if first is None else {"name": first}
    kw2 = {} if second is None else {"name": second}
    die = _die()
    s.add_contributor(fx.NodalContact(c["top"], die, penalty=1.0, **kw1))
    other = fx.Plane((0, 0, 2), (0, 0, -1), name="upper") if tool is None else \
        (die if tool == "same" else tool)
    s.add_contributor(fx.NodalContact(c["top"], other, penalty=1.0, **kw2))


def _contact_and(c, kind):
    """A contact named 'base', then a reaction or a symmetry plane named 'base'."""
    s = _sim(c)
    s.add_contributor(fx.NodalContact(c["top"], _die(), penalty=1.0, name="base"))
    f = s.facets(c["ft"], TAGS["z0"])
    if kind == "reaction":
        s.add_reaction("base", f)
    else:
        s.add_symmetry_plane(f, (0, 0, 1), name="base")


def _reaction_and_plane(c):
    s = _sim(c)
    s.add_reaction("x0", s.facets(c["ft"], TAGS["x0"]))
    s.add_symmetry_plane(s.facets(c["ft"], TAGS["x0"]), (1, 0, 0), name="x0")


#: (case id, what is done, error class, key words of the message (regex))
CASES = [
    # material and solver parameters
    ("norton-hoff-K<=0", lambda c: fx.NortonHoff(K=0.0, m=0.2), ValueError, "K"),
    ("norton-hoff-m-out-of-range", lambda c: fx.NortonHoff(K=1.0, m=1.5), ValueError, "m"),
    ("norton-hoff-regularization<=0", lambda c: fx.NortonHoff(1.0, 0.2, regularization=0.0),
     ValueError, "regularization"),
    ("elastic-E<=0", lambda c: fx.LinearElastic(-5.0, 0.3), ValueError, "E"),
    ("elastic-nu=0.5", lambda c: fx.LinearElastic(1.0, 0.5), ValueError, "nu"),
    ("solver-rtol<0", lambda c: fx.SolverOptions(rtol=-1.0), ValueError, "rtol.*>= 0"),
    ("solver-ftol-nan", lambda c: fx.SolverOptions(ftol=float("nan")), ValueError, "ftol.*>= 0"),
    ("solver-max_it<1", lambda c: fx.SolverOptions(max_it=0), ValueError, "max_it.*>= 1"),
    ("solver-unknown-line-search", lambda c: fx.SolverOptions(line_search="wolfe"), ValueError,
     "unknown line search 'wolfe'"),
    ("solver-unknown-linear-solver", lambda c: fx.SolverOptions(linear_solver="superlu9"),
     ValueError, "unknown linear solver"),
    ("solver-reuse-factorisation-not-a-flag",
     lambda c: fx.SolverOptions(reuse_factorisation="yes"), ValueError,
     "reuse_factorisation must be 'auto', True or False"),
    ("solver-reuse-factorisation-iterative",
     lambda c: fx.SolverOptions(linear_solver="condensed-amg", reuse_factorisation=True),
     ValueError, "reuse_factorisation=True needs the condensed direct linear solver.*"
                 "reuse_factorisation=False"),
    ("solver-reuse_max_krylov<1", lambda c: fx.SolverOptions(reuse_max_krylov=0), ValueError,
     "reuse_max_krylov must be an integer >= 1"),
    ("space-unknown-element", lambda c: fx.MixedSpace(c["msh"], element="P3"), ValueError,
     "unknown element 'P3'"),
    ("space-mini-quadrature<4", lambda c: fx.MixedSpace(c["msh"], quadrature_degree=3),
     ValueError, "MINI needs quadrature_degree >= 4"),
    ("simulation-material-not-a-material", lambda c: fx.Simulation(c["space"], "steel"),
     ValueError, "material must be a fxcontact material"),
    ("simulation-output_every<1", lambda c: _sim(c, output_every=0), ValueError,
     "output_every must be >= 1"),
    ("simulation-checkpoint_every<0", lambda c: _sim(c, checkpoint_every=-1), ValueError,
     "checkpoint_every must be an integer >= 0"),
    ("simulation-checkpoints-without-output_dir", lambda c: _sim(c, checkpoint_every=5),
     ValueError, "checkpoint_every needs an output_dir"),
    # meshes and boundaries
    ("mesh-missing-tag", lambda c: fx.facets_with_tags(c["msh"], c["ft"], 7), ValueError,
     r"boundary tag 7 is not present.*tags present: \[1, 2, 3, 4\]"),
    ("mesh-degenerate-cell", _degenerate_mesh, ValueError, "degenerate .*zero-volume"),
    ("mesh-nearly-degenerate-cell", _nearly_flat_mesh, ValueError,
     r"degenerate .*zero-volume.*below 1e-10 x the mean cell volume.*remesh"),
    ("mesh-tangled", _tangled_mesh, ValueError,
     r"tangled: \d+ facet\(s\) have both their cells on the same side.*inside out.*remesh"),
    ("contact-tags-missing", lambda c: fx.ContactBoundary(c["space"], c["ft"]), ValueError,
     "facet_tags given without tags"),
    ("contact-taylor-hood", lambda c: fx.ContactBoundary(
        fx.MixedSpace(c["msh"], element="taylor-hood"), c["ft"], 4), ValueError,
     "P1 velocity trace"),
    ("bc-component-out-of-range", lambda c: _sim(c).add_velocity_bc(
        fx.facets_with_tags(c["msh"], c["ft"], 3), 0.0, component=3), ValueError,
     r"component must be in \[0, 3\)"),
    ("bc-vector-of-wrong-shape", lambda c: _sim(c).add_velocity_bc(
        fx.facets_with_tags(c["msh"], c["ft"], 3), (0.0, 1.0)), ValueError,
     r"vector value must have shape \(3,\)"),
    ("bc-added-after-start", _add_bc_after_start, RuntimeError, "already set up"),
    ("facets-empty-tag-list", lambda c: _sim(c).facets(c["ft"], []), ValueError,
     r"Simulation.facets\(facet_tags\): the tag list is empty: give at least one tag"),
    ("contact-empty-tag-list", lambda c: fx.ContactBoundary(c["space"], c["ft"], []),
     ValueError, r"ContactBoundary\(facet_tags\): the tag list is empty"),
    ("bc-no-facets", lambda c: _sim(c).add_velocity_bc(np.zeros(0, np.int32), 0.0, 2),
     ValueError, r"add_velocity_bc\(facets\): no facets on any rank"),
    ("bc-facets-not-integers", lambda c: _sim(c).add_velocity_bc(np.array([0.5, 1.5]), 0.0, 2),
     ValueError, r"add_velocity_bc\(facets\) must be a 1-D array of integer facet indices"),
    ("bc-function-of-wrong-shape", lambda c: _sim(c).add_velocity_bc(
        fx.facets_with_tags(c["msh"], c["ft"], 3), lambda x: np.zeros((2, x.shape[1]))),
     ValueError, r"add_velocity_bc\(value\): the value function f\(x\) returns shape "
                 r"\(2, \d+\) for x of shape \(3, \d+\), expected \(3, \d+\)"),
    ("simulation-output_dir-is-a-file", _output_dir_is_a_file, ValueError,
     r"output_dir '.*results' is a file, not a directory: give a directory path"),
    # condensation of the bubble in the element (fxcontact.element.tensors)
    ("condense-not-mini", lambda c: ec.P1P1Layout(
        fx.MixedSpace(c["msh"], element="taylor-hood").W), ValueError,
     "needs a MINI space.*MixedSpace\\(msh, 'mini'\\)"),
    ("condense-facet-term", _condensed_facet_term, ValueError,
     "L: .*cell integrals over the whole mesh only.*assemble facet or subdomain terms apart"),
    ("condense-hand-kernel-other-law", lambda c: ec.NortonHoffElementTensors(
        ec.P1P1Layout(c["space"].W), c["space"], _OwnNortonHoff(1.0, 0.2),
        dolfinx.fem.Function(c["space"].W)), ValueError,
     "hand-written kernel is NortonHoff's own law.*_OwnNortonHoff use FFCxElementTensors"),
    ("condense-degenerate-cell", _condensed_degenerate, RuntimeError,
     "singular interior \\(bubble\\) block in a cell: degenerate element"),
    # the same object twice, names whose history columns clash
    ("simulation-contributor-added-twice", lambda c: _add_twice(c, "contributor"), ValueError,
     r"contributor NodalContact 'contact' is already added.*added twice.*add it once"),
    ("simulation-controller-added-twice", lambda c: _add_twice(c, "controller"), ValueError,
     r"controller object is already added.*add it once"),
    ("simulation-contributor-not-a-contributor", lambda c: _sim(c).add_contributor(object()),
     ValueError, r"add_contributor\(contributor\): object is not a contributor.*evaluate\(w, "
                 r"jacobian\).*stable\(\).*add_controller"),
    ("contact-tools-same-name", lambda c: fx.NodalContact(
        c["top"], [fx.Plane((0, 0, 1), (0, 0, -1)), fx.Plane((0, 0, 0), (0, 0, 1))]),
     ValueError, r"distinct names.*named \['plane'\].*pass a distinct name= to each tool"),
    ("history-name-two-default-contacts", _two_contacts, ValueError,
     r"name 'contact' of NodalContact 'contact' is already the name of NodalContact "
     r"'contact'.*overwrite each other; pass a distinct name="),
    ("history-name-tool-in-two-contacts", lambda c: _two_contacts(c, "c1", "c2", "same"),
     ValueError, r"name 'die' of tool 'die' of NodalContact 'c2' is already the name of tool "
     r"'die' of NodalContact 'c1'.*pass a distinct name="),
    ("history-name-contact-and-tool", lambda c: _two_contacts(
        c, "c1", "die", fx.Plane((0, 0, 2), (0, 0, -1), name="upper")), ValueError,
     r"name 'die' of NodalContact 'die' is already the name of tool 'die'.*pass a distinct "
     r"name="),
    ("history-name-contact-and-reaction", lambda c: _contact_and(c, "reaction"), ValueError,
     r"name 'base' of reaction 'base' is already the name of NodalContact 'base'.*name="),
    ("history-name-contact-and-symmetry-plane", lambda c: _contact_and(c, "plane"), ValueError,
     r"name 'base' of symmetry plane 'base' is already the name of NodalContact 'base'"),
    ("history-name-reaction-and-symmetry-plane", _reaction_and_plane, ValueError,
     r"name 'x0' of symmetry plane 'x0' is already the name of reaction 'x0'.*name="),
    # tools
    ("plane-zero-normal", lambda c: fx.Plane((0, 0, 0), (0, 0, 0)), ValueError, "non-zero"),
    ("sphere-negative-radius", lambda c: fx.Sphere((0, 0, 0), -1.0), ValueError,
     "radius must be a positive finite number"),
    ("cylinder-nan-point", lambda c: fx.Cylinder((0, np.nan, 0), (0, 0, 1), 1.0), ValueError,
     "finite 3-vector"),
    ("cone-half-angle-out-of-range", lambda c: fx.Cone((0, 0, 0), (0, 0, 1), 2.0), ValueError,
     "half_angle"),
    ("profile-zero-length-segment", lambda c: fx.RevolvedProfile(
        [(0, 1), (1, 1), (1, 1), (2, 2)], inside=False), ValueError, "zero length"),
    ("profile-below-axis", lambda c: fx.RevolvedProfile([(0, 1), (1, -1)], inside=False),
     ValueError, "< 0"),
    ("profile-self-intersecting", lambda c: fx.RevolvedProfile(
        [(0, 2), (3, 2), (3, 3), (1, 1), (5, 1)], inside=False), ValueError,
     r"intersects itself: segment 0 \(line\) and segment 2"),
    ("facets-non-manifold", lambda c: fx.FacetedTool(
        np.r_[_TET, [[1, 1, 1]]], np.r_[_TET_T, [[1, 2, 4]]]), ValueError,
     "non-manifold edges"),
    ("facets-inside-out", lambda c: fx.FacetedTool(_TET, _TET_T[:, ::-1]), ValueError,
     "normals point into the tool"),
    ("facets-inconsistent-orientation", lambda c: fx.FacetedTool(
        _TET, np.r_[_TET_T[:3], _TET_T[3:, ::-1]]), ValueError, "inconsistent orientation"),
    ("facets-degenerate-triangle", lambda c: fx.FacetedTool(
        np.r_[_TET, [[0.5, 0, 0]]], np.r_[_TET_T, [[0, 1, 4]]]), ValueError,
     "degenerate .*zero-area"),
    ("facets-nan-vertex", lambda c: fx.FacetedTool(np.r_[_TET[:3], [[0, 0, np.nan]]], _TET_T),
     ValueError, "NaN/inf coordinates"),
    # contact and friction parameters
    ("contact-unknown-scheme", lambda c: fx.NodalContact(c["top"], _die(), scheme="exact"),
     ValueError, "unknown contact scheme 'exact'"),
    ("contact-penalty<=0", lambda c: fx.NodalContact(c["top"], _die(), penalty=-1.0),
     ValueError, "penalty must be finite and > 0"),
    ("contact-no-tool", lambda c: fx.NodalContact(c["top"], []), ValueError,
     "non-empty sequence of Tools"),
    ("friction-coulomb-mu<0", lambda c: fx.Coulomb(-0.1), ValueError, "mu"),
    ("friction-tresca-mbar>1", lambda c: fx.Tresca(1.5), ValueError, "mbar"),
    ("friction-shear-limit-value-and-rate", lambda c: fx.ShearLimit(value=10.0, strain_rate=1.0),
     ValueError, r"ShearLimit: give the shear limit k \(value=\) or the strain rate"),
    ("friction-shear-limit-rate<=0", lambda c: fx.Tresca(0.5, fx.ShearLimit.at_strain_rate(0.0)),
     ValueError, r"ShearLimit strain_rate must be finite and in \(0"),
    ("friction-unknown-tool", lambda c: fx.NodalContact(
        c["top"], _die(), penalty=1.0, friction={"roll": fx.Coulomb(0.3)}), ValueError,
     "friction given for tool 'roll'"),
    ("friction-slip-velocity<=0", lambda c: fx.NodalContact(
        c["top"], _die(), penalty=1.0, friction=fx.Coulomb(0.3), slip_velocity=0.0),
     ValueError, "slip_velocity"),
    ("linear-solver-unknown-kind", lambda c: _contact_problem(c, 1).use_linear_solver(
        None, "amg"), ValueError, r"use_linear_solver: unknown kind 'amg'; choose one of"),
    ("linear-solver-iterative-not-vector-p1", lambda c: _contact_problem(c, 2).use_linear_solver(
        None, "iterative"), ValueError,
     r"kind='iterative' .* needs u in a vector P1 space .* use kind='direct'"),
    ("linear-solver-not-a-solver", lambda c: _contact_problem(c, 1).use_linear_solver(
        "mumps", "direct"), ValueError,
     "solver must be a dolfinx NewtonSolver, a petsc4py SNES or KSP, got str"),
    ("springs-negative-stiffness", lambda c: fx.NodalSprings(c["top"], -1.0), ValueError,
     "stiffness must be finite and >= 0"),
    # time stepping
    ("step-dt<=0", lambda c: _sim(c).step(0.0), ValueError, "dt must be a finite number > 0"),
    ("step-dt-nan", lambda c: _sim(c).step(float("nan")), ValueError, "dt must be a finite"),
    ("step-max_cutbacks<0", lambda c: _sim(c).step(0.1, max_cutbacks=-1), ValueError,
     "max_cutbacks must be >= 0"),
    ("run-t_end-before-t", _run_time_backwards, ValueError, "t_end must be > current time 1.0"),
    ("run-dt<=0", lambda c: _sim(c).run(1.0, -0.1), ValueError, "dt must be a finite"),
]


@pytest.mark.parametrize("case,make,exc,words", CASES, ids=[c[0] for c in CASES])
def test_bad_input(ctx, case, make, exc, words):
    with pytest.raises(exc, match=words) as e:
        make(ctx)
    assert type(e.value) is exc or issubclass(type(e.value), exc)


def test_catalogue_is_large_and_listed_in_the_readme():
    ids = [c[0] for c in CASES] + RUN_TIME_CASES + [c[0] for c in SUBPROCESS_CASES]
    assert len(ids) >= 30 and len(set(ids)) == len(ids)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    missing = [i for i in ids if f"`{i}`" not in readme]
    assert not missing, f"README table lacks {missing}"


# ----------------------------------------------------------------------------- during a run
RUN_TIME_CASES = ["bc-function-returns-nan", "bc-function-returns-wrong-shape",
                  "checkpoint-corrupted", "newton-fails-after-all-cutbacks",
                  "disk-full-history", "disk-full-vtk", "disk-full-checkpoint",
                  "checkpoint-of-another-mesh",
                  "tool-starts-buried", "friction-needs-shear-limit",
                  "tool-holds-the-body", "history-column-clash", "second-run-continues-the-outputs",
                  "new-run-over-another-runs-checkpoints", "checkpoint-of-other-parameters"]


def _pressed(c, out, top=-0.1, **kw):
    s = fx.Simulation(c["space"], fx.NortonHoff(1.0, 0.2), progress=False, output_dir=out,
                      name="p", **kw)
    for tag, comp in (("x0", 0), ("y0", 1), ("z0", 2)):
        s.add_velocity_bc(s.facets(c["ft"], TAGS[tag]), 0.0, comp)
    s.add_velocity_bc(s.facets(c["ft"], TAGS["z1"]), top, 2)
    return s


def _outputs_intact(out, n_rows, times):
    """The CSV holds exactly the rows 1..n_rows (parsable numbers), the .pvd the given times and
    every file it references exists."""
    COMM.barrier()
    if COMM.rank == 0:
        with open(os.path.join(out, "p_history.csv"), newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert [int(r["increment"]) for r in rows] == list(range(1, n_rows + 1))
        assert all(np.isfinite(float(r["volume"])) for r in rows)
        pvd = read_pvd(os.path.join(out, "p.pvd"))
        assert [t for t, _ in pvd] == pytest.approx(times, abs=1e-12)
        assert all(os.path.exists(os.path.join(out, f)) for _, f in pvd)
    COMM.barrier()


@pytest.fixture
def out():
    d = shared_tmpdir("fxc_bad_")
    yield d
    COMM.barrier()
    if COMM.rank == 0:
        shutil.rmtree(d, ignore_errors=True)


def test_bc_function_returns_nan(cube, out):
    s = _pressed(cube, out, top=lambda t: -0.1 if t < 0.15 else float("nan"))
    with pytest.raises(ValueError, match=r"condition\(s\) #\[3\].*non-finite.*t = 0.2"):
        s.run(0.4, 0.1)
    _outputs_intact(out, 1, [0.0, 0.1])


def test_bc_function_returns_wrong_shape(cube, out):
    """The message names the condition (number, component, facets), the time, the shapes."""
    s = _pressed(cube, out, top=lambda x, t: np.full(x.shape[1], -0.1) if t < 0.15
                 else np.full((2, x.shape[1]), -0.1))
    with pytest.raises(ValueError, match=r"velocity boundary condition #3 \(component 2, on \d+ "
                                         r"facets\) at t = 0.2: the value function f\(x\) "
                                         r"returns shape \(2, \d+\) .*expected \(\d+,\)"):
        s.run(0.4, 0.1)
    _outputs_intact(out, 1, [0.0, 0.1])


def _damage(path, how):
    """Truncate ``path`` or flip one byte in its middle (rank 0)."""
    if COMM.rank == 0:
        data = bytearray(Path(path).read_bytes())
        if how == "truncate":
            data = data[: len(data) // 2]
        else:
            data[len(data) // 2] ^= 0xFF
        Path(path).write_bytes(bytes(data))
    COMM.barrier()


def test_checkpoint_corrupted(cube, out):
    """A truncated or altered checkpoint is refused with a CheckpointError naming the file and
    the newest intact checkpoint to resume from; resume() does not fall back by itself."""
    s = _pressed(cube, out, checkpoint_every=1, checkpoint_keep=3)
    s.run(0.3, 0.1)
    ckpts = os.path.join(out, "checkpoints")
    p1, p2, p3 = (os.path.join(ckpts, f"p_{i:06d}") for i in (1, 2, 3))
    _damage(os.path.join(p3, "rank0.npz"), "truncate")
    with pytest.raises(CheckpointError, match=rf"checkpoint {re.escape(p3)} is corrupted "
                                              rf"\(rank0.npz: BadZipFile.*the newest intact "
                                              rf"checkpoint is {re.escape(p2)}: resume\(path="):
        _pressed(_cube(), out).resume()
    _damage(os.path.join(p2, f"rank{COMM.size - 1}.npz"), "flip")
    with pytest.raises(CheckpointError, match=rf"{re.escape(p2)} is corrupted .*Bad CRC-32.*"
                                              rf"newest intact checkpoint is {re.escape(p1)}"):
        _pressed(_cube(), out).resume(p2)
    _outputs_intact(out, 3, [0.0, 0.1, 0.2, 0.3])
    s2 = _pressed(_cube(), out)
    s2.resume(p1)
    assert s2.increment == 1
    s2.close()


class _RefuseAfter:
    """A contributor that refuses every iterate from t = t0 on (a Newton solve that cannot
    succeed, whatever the cut-backs)."""

    def __init__(self, t0):
        self.t0, self.t = t0, 0.0

    def begin_increment(self, sim, t, dt, x):
        self.t = t

    def evaluate(self, w, jacobian):
        if self.t >= self.t0 - 1e-12:
            raise fx.ContributorError("refused")
        return fx.NodalTerms.empty(3)

    def stable(self):
        return True


def test_newton_fails_after_all_cutbacks(cube, out):
    s = _pressed(cube, out, checkpoint_every=10)
    s.add_contributor(_RefuseAfter(0.2))
    with pytest.raises(IncrementError, match=r"t = 0.2 failed.*refused.*Results up to t = 0.2"):
        s.run(0.5, 0.1, max_cutbacks=2)
    _outputs_intact(out, 2, [0.0, 0.1, 0.2])
    # a checkpoint of the last accepted state was written at the failure
    assert latest_checkpoint(os.path.join(out, "checkpoints"), "p").endswith("p_000002")


def test_disk_full_history(cube, out, monkeypatch):
    write = HistoryWriter.write
    calls = []

    def failing(self, row):     # rank 0 writes the CSV: the error must reach every rank
        calls.append(1)
        if len(calls) == 2 and self.comm.rank == 0:
            raise OSError(28, "No space left on device")
        write(self, row)

    monkeypatch.setattr(HistoryWriter, "write", failing)
    s = _pressed(cube, out)
    with pytest.raises(OutputError, match=r"increment 2 .*No space left on device.*intact"):
        s.run(0.4, 0.1)
    _outputs_intact(out, 1, [0.0, 0.1])


def test_disk_full_vtk(cube, out, monkeypatch):
    write = SeriesWriter.write
    calls = []

    def failing(self, functions, t):
        calls.append(1)
        if len(calls) == 3:      # the initial state and increment 1 are written
            raise OSError(28, "No space left on device")
        write(self, functions, t)

    monkeypatch.setattr(SeriesWriter, "write", failing)
    s = _pressed(cube, out)
    with pytest.raises(OutputError, match=r"increment 2 .*No space left on device"):
        s.run(0.4, 0.1)
    _outputs_intact(out, 2, [0.0, 0.1])


def test_disk_full_checkpoint(cube, out, monkeypatch):
    import fxcontact.checkpoint as ck
    savez = np.savez
    calls = []

    def failing(fh, **arrays):   # the third checkpoint fails on the last rank
        calls.append(1)
        if len(calls) == 3 and COMM.rank == COMM.size - 1:
            raise OSError(28, "No space left on device")
        savez(fh, **arrays)

    monkeypatch.setattr(ck.np, "savez", failing)
    s = _pressed(cube, out, checkpoint_every=1, checkpoint_keep=5)
    with pytest.raises(OutputError, match=r"cannot write checkpoint .*p_000003.*No space left"
                       r".*increment 3.*previous checkpoint .*p_000002 is intact"):
        s.run(0.5, 0.1)
    monkeypatch.undo()
    _outputs_intact(out, 3, [0.0, 0.1, 0.2, 0.3])
    assert latest_checkpoint(os.path.join(out, "checkpoints"), "p").endswith("p_000002")
    s2 = _pressed(_cube(), out)      # the same initial mesh
    s2.resume()
    assert s2.increment == 2
    s2.close()


def test_checkpoint_of_another_mesh(cube, out):
    s = _pressed(cube, out, checkpoint_every=1)
    s.run(0.1, 0.1)
    path = latest_checkpoint(os.path.join(out, "checkpoints"), "p")
    manifest = Path(path, "manifest.json").read_bytes()
    msh = box_mesh(COMM, n=(2, 2, 2), perturb=0.1)        # same sizes, moved interior nodes
    other = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(1.0, 0.2), progress=False,
                          output_dir=out, name="p")
    with pytest.raises(CheckpointError, match="different mesh"):
        other.resume(path)
    # the refused checkpoint and the outputs are untouched
    assert Path(path, "manifest.json").read_bytes() == manifest
    _outputs_intact(out, 1, [0.0, 0.1])


def test_tool_starts_buried(cube, out):
    s = _pressed(cube, out)
    s.add_contributor(fx.NodalContact(fx.ContactBoundary(cube["space"], cube["ft"], TAGS["z1"]),
                                      _die(z=0.6), penalty=10.0))
    with pytest.raises(ValueError, match=r"buried in tool 'die' deeper than the limit"):
        s.run(0.2, 0.1)
    _outputs_intact(out, 0, [0.0])


def test_friction_needs_shear_limit(cube, out):
    s = fx.Simulation(cube["space"], fx.LinearElastic(100.0, 0.3), progress=False,
                      output_dir=out, name="p")
    s.add_velocity_bc(s.facets(cube["ft"], TAGS["z0"]), 0.0)
    s.add_contributor(fx.NodalContact(fx.ContactBoundary(cube["space"], cube["ft"], TAGS["z1"]),
                                      _die(), penalty=10.0, friction=fx.Tresca(0.5)))
    with pytest.raises(ValueError, match=r"shear flow stress k .*give shear_limit="):
        s.run(0.2, 0.1)
    _outputs_intact(out, 0, [0.0])


# ------------------------------------------- set-ups that used to crash or hang (subprocess)
DRIVER = Path(__file__).resolve().parent / "bad_setup_driver.py"

#: (case id, ranks, error class, key words of the message on every rank (regex)): facets of
#: another mesh used to crash the assembly (SIGSEGV); a set-up that differs between ranks used
#: to leave one rank raising and the other waiting forever
SUBPROCESS_CASES = [
    ("contact-facet-tags-of-another-mesh", (1, 2), "ValueError",
     r"ContactBoundary\(facet_tags\): .*facet tags of another mesh\?"),
    ("facets-tags-of-another-mesh", (1, 2), "ValueError",
     r"Simulation.facets\(facet_tags\): .*facet tags of another mesh\?"),
    ("bc-facets-of-another-mesh", (1, 2), "ValueError",
     r"add_velocity_bc\(facets\): facet index \d+ .*out of range.*facet tags of another mesh\?"),
    ("reaction-facets-of-another-mesh", (1, 2), "ValueError",
     r"add_reaction\(facets\): facet index \d+ .*out of range"),
    ("symmetry-plane-interior-facets", (1, 2), "ValueError",
     r"add_symmetry_plane\(facets\): .*not on the boundary"),
    ("contributor-added-on-one-rank", (2,), "ValueError",
     r"set-up differs between ranks: rank 0 in add_contributor\(\); rank 1 in Simulation.run"),
    ("contact-created-on-one-rank", (2,), "ValueError",
     r"set-up differs between ranks: rank 0 in ContactBoundary\(\); rank 1 in Simulation.run"),
    ("tool-none-on-one-rank", (2,), "ValueError",
     r"tools must be a Tool.*raised on rank 1 only: the set-up differs between ranks"),
    ("tool-parameters-differ", (2,), "ValueError",
     r"add_contributor\(\): contributor differs between ranks \(rank 0: .*velocity=\[0, 0, "
     r"-0.1\].*rank 1: .*velocity=\[0, 0, -0.2\]"),
    ("dt-differs", (2,), "ValueError", r"Simulation.run\(\): dt differs between ranks "
                                       r"\(rank 0: 0.1; rank 1: 0.05\)"),
    ("bc-added-on-one-rank", (2,), "ValueError",
     r"set-up differs between ranks: rank 0 in facets_with_tags\(\); rank 1 in Simulation.run"),
]


def _run_driver(case, nranks, timeout=HANG_TIMEOUT):
    """Run the driver under ``mpirun -n nranks`` in its own process group; kill the group and
    fail if it hangs."""
    import tempfile
    out = tempfile.mkdtemp(prefix="fxc_bad_setup_")
    rc, text = run_script(DRIVER, [case, out], nranks, timeout)
    assert rc == 0, f"{case} on {nranks} rank(s): exit code {rc}\n{text[-3000:]}"
    files = sorted(Path(out).glob("rank*.txt"))
    results = [f.read_text() for f in files]
    shutil.rmtree(out, ignore_errors=True)
    return results


@pytest.mark.serial
@pytest.mark.parametrize("case,ranks,exc,words", SUBPROCESS_CASES,
                         ids=[c[0] for c in SUBPROCESS_CASES])
@pytest.mark.slow
def test_bad_setup_neither_crashes_nor_hangs(case, ranks, exc, words):
    """Each rank raises the same error class with the words naming the argument and the fix
    (run from the serial session: the driver is its own 1- and 2-rank MPI job)."""
    for n in ranks:
        results = _run_driver(case, n)
        assert len(results) == n, (case, n, results)
        for r in results:
            assert r.startswith(f"{exc}: ") and re.search(words, r), (case, n, r)


# ------------------------------------------------ silent wrong answers and lost outputs
def _die_run(c, out, K=1.0, m=0.2, mu=0.2, speed=0.1, tool=None, **kw):
    """The cube on its symmetry planes pressed by a die with Coulomb friction (a contact)."""
    s = fx.Simulation(c["space"], fx.NortonHoff(K, m), progress=False, output_dir=out,
                      name="p", **kw)
    for tag, comp in (("x0", 0), ("y0", 1), ("z0", 2)):
        s.add_velocity_bc(s.facets(c["ft"], TAGS[tag]), 0.0, comp)
    tool = fx.Plane((0, 0, 1), (0, 0, -1), velocity=(0, 0, -speed), name="die") \
        if tool is None else tool
    s.add_contributor(fx.NodalContact(fx.ContactBoundary(c["space"], c["ft"], TAGS["z1"]),
                                      tool, penalty=10.0, friction=fx.Coulomb(mu)))
    return s


@pytest.mark.parametrize("tool,words", [
    (fx.Plane((0, 0, 1), (0, 0, 1), velocity=(0, 0, -0.1), name="die"),
     r"flip the normal \(normal=\(0.0, 0.0, -1.0\)"),
    (fx.Cylinder((0.5, 0.5, 0), (0, 0, 1), 3.0, inside=False, name="ring"),
     r"set inside=True")], ids=["plane-normal-into-the-body", "cylinder-inside-out"])
def test_tool_holds_the_body(cube, out, tool, words):
    """A tool turned the wrong way holds the whole body: no node would ever touch it."""
    s = _die_run(cube, out, tool=tool)
    with pytest.raises(ValueError, match=rf"tool '{tool.name}' of contact 'contact' holds the "
                       rf"whole body at t = 0.*zero force.*{words}"):
        s.run(0.2, 0.1)
    _outputs_intact(out, 0, [0.0])


def test_boundary_facets_with_ghosts_are_accepted():
    """A mesh with ghost facets (ghost mode ``shared_facet``, as the meshing builders make):
    the boundary facets found on each rank, ghosts where the partition meets the boundary
    included, are accepted where exterior facets are required (dolfinx lists the owned
    exterior facets only, so a ghost must not be taken for an interior facet)."""
    from fxcontact.spaces import checked_facets
    msh = dolfinx.mesh.create_unit_cube(COMM, 4, 4, 4,
                                        ghost_mode=dolfinx.mesh.GhostMode.shared_facet)
    # the facets on the cube's faces among all the local ones (ghosts included)
    every = np.unique(np.concatenate([dolfinx.mesh.locate_entities(
        msh, 2, (lambda c, v: lambda x: np.isclose(x[c], v))(c, v))
        for c in range(3) for v in (0.0, 1.0)]))
    n_ghost = COMM.allreduce(int(np.sum(every >= msh.topology.index_map(2).size_local)))
    assert (n_ghost > 0) == (COMM.size > 1)      # the case is there on 2 ranks
    assert np.array_equal(checked_facets(msh, every, "boundary", exterior=True), every)
    x0 = dolfinx.mesh.locate_entities_boundary(msh, 2, lambda x: np.isclose(x[0], 0.0))
    sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(1.0, 0.2), progress=False)
    sim.add_symmetry_plane(x0, (1.0, 0.0, 0.0), name="x0")


@pytest.mark.parametrize("tool", [
    fx.Plane((0, 0, 1.2), (0, 0, -1), velocity=(0, 0, -0.1), name="die"),
    fx.Cylinder((0.5, 0.5, 0), (0, 0, 1), 3.0, inside=True, velocity=(0, 0, -0.1),
                name="bore")],
    ids=["die-away-from-the-body", "bore-around-the-body"])
def test_tool_placed_right_is_accepted(cube, out, tool):
    s = _die_run(cube, out, tool=tool)
    s.run(0.1, 0.1)
    _outputs_intact(out, 1, [0.0, 0.1])


class _WritesVolume:
    """A contributor whose history column is one of the simulation's own."""

    def evaluate(self, w, jacobian):
        return fx.NodalTerms.empty(3)

    def stable(self):
        return True

    def diagnostics(self):
        return {"volume": 1.0}


def test_history_column_clash(cube, out):
    s = _pressed(cube, out)
    s.add_contributor(_WritesVolume())
    with pytest.raises(ValueError, match=r"history column\(s\) \['volume'\] of _WritesVolume "
                       r"are already written.*pass a distinct name="):
        s.run(0.2, 0.1)
    _outputs_intact(out, 0, [0.0])


def test_second_run_continues_the_outputs(cube, out):
    """run() closes the outputs; a second run() (and a step() after it) continues them."""
    s = _pressed(cube, out)
    s.run(0.2, 0.1)
    s.run(0.4, 0.1)
    _outputs_intact(out, 4, [0.0, 0.1, 0.2, 0.3, 0.4])
    s.step(0.1)
    s.close()
    _outputs_intact(out, 5, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    assert len(s.history) == 5


def _files(out):
    """The CSV and .pvd of run 'p' and the names of its checkpoints (rank 0's view)."""
    if COMM.rank != 0:
        return None
    ckpts = [os.path.basename(p) for p in list_checkpoints(os.path.join(out, "checkpoints"))]
    return (Path(out, "p_history.csv").read_bytes(), Path(out, "p.pvd").read_bytes(), ckpts)


def _no_wall(history):
    """The history without its wall times (measured per rank)."""
    return [{k: v for k, v in r.items() if not k.startswith("wall_")} for r in history]


def test_force_tolerance_without_contact_warns(cube, out, caplog):
    """``SolverOptions.ftol`` on a problem with no contributor that reports a nodal force
    norm (no contact): a warning, once per solver, says it has no effect, and Newton
    converges on rtol."""
    s = _pressed(cube, out, solver_options=fx.SolverOptions(ftol=1e-3))
    with caplog.at_level("WARNING", logger="fxcontact.newton.solver"):
        s.run(0.2, 0.1)
    assert "ftol = 0.001 has no effect: no contributor reports force_norm()" in caplog.text
    assert caplog.text.count("has no effect") == 1
    assert len(s.history) == 2
    s.close()


def test_new_run_over_another_runs_checkpoints(cube, out, caplog):
    first = _die_run(cube, out, checkpoint_every=1)
    first.run(0.2, 0.1)
    before = _files(out)
    second = _die_run(_cube(), out, speed=0.2, checkpoint_every=1)
    with pytest.raises(CheckpointError, match=rf"{re.escape(os.path.join(out, 'checkpoints'))} "
                       r"holds checkpoints of another run named 'p' \(p_000001, p_000002\).*"
                       r"resume\(\).*another output_dir.*another name.*overwrite=True"):
        second.run(0.2, 0.1)
    assert _files(out) == before      # nothing of the first run touched
    _outputs_intact(out, 2, [0.0, 0.1, 0.2])
    # overwrite=True: the old checkpoints go (with a warning), resume() takes the new run's
    third = _die_run(_cube(), out, speed=0.2, checkpoint_every=1, overwrite=True)
    with caplog.at_level("WARNING", logger="fxcontact.simulation"):
        third.run(0.1, 0.1)
    assert "removing the checkpoints of the previous run p_000001, p_000002" in caplog.text
    assert COMM.rank != 0 or _files(out)[2] == ["p_000001"]
    again = _die_run(_cube(), out, speed=0.2)
    again.resume()
    assert _no_wall(again.history) == _no_wall(third.history)
    again.close()


@pytest.mark.parametrize("change,words", [
    ({"K": 2.0}, r"material_parameters\.K: 1\.0 in the checkpoint, 2\.0 in this run"),
    ({"m": 0.3}, r"material_parameters\.m: 0\.2 in the checkpoint, 0\.3 in this run"),
    ({"mu": 0.3}, r"contributor_parameters\[0\]\.friction\[0\]\.mu: 0\.2 in the checkpoint, "
                  r"0\.3 in this run"),
    ({"speed": 0.2}, r"tools\[0\]\.motion\.velocity: \[0, 0, -0\.1\] in the checkpoint, "
                     r"\[0, 0, -0\.2\] in this run")],
    ids=["K", "m", "friction-mu", "die-speed"])
def test_checkpoint_of_other_parameters(cube, out, change, words):
    s = _die_run(cube, out, checkpoint_every=1)
    s.run(0.2, 0.1)
    before = _files(out)
    other = _die_run(_cube(), out, **change)
    with pytest.raises(CheckpointError, match=r"different set-up: .*" + words +
                       r".*Resume with the set-up of the checkpointed run"):
        other.resume()
    assert _files(out) == before


@pytest.mark.parametrize("z, speed, touched", [(1.5, 0.1, False), (1.0, 0.3, True)])
def test_run_without_contact_is_said(cube, out, caplog, z, speed, touched):
    """A die that never reaches the body (0.5 mm above its top, both moving down at 0.1 mm/s):
    the contact's summary line and a warning say that no node ever touched it (the forces are
    zero: positions, motions, units); a die that touches says nothing of the kind."""
    s = _pressed(cube, out)
    die = fx.Plane((0, 0, z), (0, 0, -1), velocity=(0, 0, -speed), name="die")
    c = fx.NodalContact(fx.ContactBoundary(cube["space"], cube["ft"], TAGS["z1"]), die,
                        penalty=10.0)
    s.add_contributor(c)
    with caplog.at_level("WARNING", logger="fxcontact.contact"):
        s.run(0.2, 0.1)
    assert ("no node ever touched 'die' in 2 increment(s)" in c.summary()) is not touched
    if COMM.rank == 0:
        assert ("no node ever touched" in caplog.text) is not touched
    s.close()


@pytest.mark.parametrize("process", ["upsetting", "drawing", "ring_rolling"])
def test_process_output_dir_refused_before_the_run(out, process):
    """A process run whose output_dir is a file is refused before its first increment, on
    every rank, with the cause (not after the whole run, nor a hang of the other ranks)."""
    from fxcontact.processes import (DrawingCase, RingRollingCase, UpsettingCase, ring_rolling,
                                     run_drawing, run_upsetting)
    runs = {"upsetting": lambda d: run_upsetting(UpsettingCase.quick(), COMM, output_dir=d),
            "drawing": lambda d: run_drawing(DrawingCase.quick(), COMM, output_dir=d),
            "ring_rolling": lambda d: ring_rolling.run(RingRollingCase().quick(), COMM,
                                                       output_dir=d)}
    path = os.path.join(out, "a_file")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write("not a directory\n")
    COMM.barrier()
    with pytest.raises(ValueError, match="is a file, not a directory.*nothing was computed"):
        runs[process](path)


def test_increment_larger_than_the_mesh_is_said():
    """dt = 1 s on the drawing moves the bar 100 mm per increment, more than the whole bar:
    refused with the dt that keeps one element per increment (it reported −119.5 MPa as
    "completed"); two elements per increment: a warning with the figure; the defaults and
    the quick cases say nothing."""
    from fxcontact.processes import DrawingCase, ExtrusionCase
    with pytest.raises(ValueError, match=r"dt = 1 s moves the drawn bar by 100 mm in one "
                                         r"increment, more than .* take dt <= 0.015 s"):
        DrawingCase.quick(dt=1.0)
    with pytest.warns(UserWarning, match=r"= 2 elements of 1.5 mm.*dt <= 0.015 s"):
        DrawingCase.quick(dt=0.03)
    with pytest.warns(UserWarning, match=r"the extruded product"):
        ExtrusionCase.quick(dt=0.1)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for case in (DrawingCase(), DrawingCase.quick(), ExtrusionCase(), ExtrusionCase.quick()):
            assert case.dt > 0
