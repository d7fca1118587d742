"""Hertz validation (THEORY §11, :mod:`fxcontact.processes.hertz_cylinder` and
:mod:`~fxcontact.processes.hertz_sphere`): small runs (serial and on 2 ranks) and the acceptance
accuracy (line contact: p_max within 3 % of Hertz for the FEM load, half-width within one
element; sphere: force–indentation within 3 %, p_max within 5 %, contact radius within one
element)."""

import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.processes import hertz_cylinder, hertz_sphere

from helpers import shared_tmpdir

@pytest.fixture
def outdir():
    return shared_tmpdir("fxc-hertz-")


def _hertz_profile_error(x, p, a, p0, upto=0.8):
    """Largest |p_n/p0 - sqrt(1 - x²/a²)| over the nodes with x < upto·a."""
    sel = x < upto * a
    return float(np.max(np.abs(p[sel] / p0 - np.sqrt(1.0 - (x[sel] / a) ** 2))))


def _check_line_contact(res, h_fine, p_tol):
    P, a, p0 = res["force"], res["hertz_half_width"], res["hertz_p_max"]
    assert P > 0
    # vertical equilibrium: the load on the tool is the reaction of the bottom roller
    assert abs(res["bottom_reaction"] - P) <= 1e-5 * P
    # Hertz for the FEM load (THEORY §11.2), validity: small a/R, large block
    assert abs(a - math.sqrt(4 * P * 5.0 / (math.pi * res["E_star"]))) < 1e-12
    assert a / 5.0 < 0.1
    assert abs(res["p_max"] / p0 - 1.0) <= p_tol, (res["p_max"], p0)
    assert abs(res["contact_half_width"] - a) <= h_fine, (res["contact_half_width"], a)
    lo, hi = res["contact_half_width_bounds"]
    assert lo <= res["contact_half_width"] <= hi
    assert abs(res["contact_half_width_area"] - a) <= h_fine
    # penalty penetration negligible against the indentation
    assert res["penetration"] < 1e-3 * res["indentation"]


# ------------------------------------------------------------------ small runs (seconds)

def test_hertz_cylinder_small(outdir):
    """Coarse line contact (~9 nodes on a): already within 3 % on p_max (measured −0.5 %) and one
    element on the half-width; the nodal profile follows the ellipse within 5 % of p0."""
    h_fine = 0.02
    res = hertz_cylinder.run(h_fine=h_fine, n_steps=2, output_dir=outdir, progress=False)
    _check_line_contact(res, h_fine, p_tol=0.03)
    assert res["nodes_on_half_width"] >= 8
    assert _hertz_profile_error(res["x"], res["p"], res["hertz_half_width"],
                                res["hertz_p_max"]) < 0.05
    assert len(res["history"]) == 2
    if MPI.COMM_WORLD.rank == 0:
        assert os.path.getsize(res["png"]) > 10_000
        assert os.path.getsize(os.path.join(outdir, "profile.csv")) > 0
        assert os.path.getsize(os.path.join(outdir, "hertz_cylinder_history.csv")) > 0


def test_hertz_cylinder_schemes_agree():
    """Pure normal indentation, no sliding: the four schemes give the same contact state
    (the explicit frozen tangent plane is exact to O((v_t dt)²/R) with v_t ≈ 0)."""
    ref = None
    for scheme in ("implicit", "explicit", "quasi-implicit", "implicit-exact"):
        res = hertz_cylinder.run(h_fine=0.03, n_steps=2, scheme=scheme, output_dir=None,
                                 picture=False, progress=False)
        if ref is None:
            ref = res
            continue
        assert abs(res["force"] / ref["force"] - 1.0) < 1e-4, scheme
        assert abs(res["p_max"] / ref["p_max"] - 1.0) < 1e-3, scheme
        assert res["nodes_on_half_width"] == ref["nodes_on_half_width"], scheme
    with pytest.raises(ValueError, match="indentation"):
        hertz_cylinder.run(indentation=-1.0, output_dir=None)


@pytest.mark.slow
def test_hertz_sphere_small(outdir):
    """Coarse sphere (5 nodes on a, size growth 0.3, 20 mm block): linear tetrahedra that coarse
    are too stiff, measured +5.3 % on the force; checked within 10 % (force) and 6 % (p_max),
    contact radius within one element."""
    h_fine = 0.05
    res = hertz_sphere.run(h_fine=h_fine, growth=0.3, width=20.0, height=20.0, h=4.0,
                           n_steps=2, output_dir=outdir, progress=False)
    P, Ph = res["force"], res["hertz_force"]
    assert abs(Ph - 4.0 / 3.0 * res["E_star"] * math.sqrt(5.0) * 0.0133**1.5) < 1e-9 * Ph
    assert abs(res["bottom_reaction"] - P) <= 1e-5 * P
    assert 0.98 < P / Ph < 1.10, (P, Ph)
    assert abs(res["p_max"] / res["hertz_p_max"] - 1.0) < 0.06
    assert abs(res["contact_radius"] - res["hertz_contact_radius"]) <= h_fine
    assert res["penetration"] < 1e-3 * res["indentation"]
    if MPI.COMM_WORLD.rank == 0:
        assert os.path.getsize(res["png"]) > 10_000
        assert os.path.getsize(res["png_deformed"]) > 10_000
        assert os.path.getsize(os.path.join(outdir, "hertz_sphere_history.csv")) > 0


# ------------------------------------------------------------------ acceptance accuracy

def test_hertz_cylinder_accuracy():
    """Default line contact (h_fine = 8 µm, ~21 nodes on a = 0.17 mm, block 10 × 10 mm ≈ 60 a):
    p_max within 3 % of p0 = 2P/(πa) for the FEM load, half-width within one element."""
    res = hertz_cylinder.run(output_dir=None, picture=False, progress=False)
    _check_line_contact(res, res["h_fine"], p_tol=0.03)
    assert res["nodes_on_half_width"] >= 20
    assert _hertz_profile_error(res["x"], res["p"], res["hertz_half_width"],
                                res["hertz_p_max"]) < 0.02


@pytest.mark.slow
def test_hertz_sphere_accuracy():
    """Default sphere (δ = 13.3 µm, h_fine = 25 µm, ~10 nodes on a = 0.258 mm, size growth 0.15,
    block 80 mm ≈ 300 a): force within 3 % of 4/3 E* R^½ δ^{3/2}, p_max within 5 % of p0,
    contact radius within one element."""
    res = hertz_sphere.run(output_dir=None, picture=False, progress=False)
    h_fine = res["h_fine"]
    assert abs(res["force"] / res["hertz_force"] - 1.0) <= 0.03, res["force"]
    assert abs(res["p_max"] / res["hertz_p_max"] - 1.0) <= 0.05, res["p_max"]
    assert abs(res["contact_radius"] - res["hertz_contact_radius"]) <= h_fine
    assert abs(res["bottom_reaction"] - res["force"]) <= 1e-5 * res["force"]


# ------------------------------------------------------------------ P1 displacement (dolfinx)

@pytest.mark.slow
def test_hertz_sphere_p1_small(outdir):
    """The sphere in P1 displacement (a plain dolfinx problem + ContactProblem), reduced size
    (h_fine = 50 µm, growth 0.15, 20 mm block): the reduced-size tolerances of the mixed test
    (force within +10 %, p_max within 6 %, radius within one element; measured +4.7 %, +5.4 %);
    equilibrium with the bottom reaction, negligible penalty penetration."""
    h_fine = 0.05
    res = hertz_sphere.run(h_fine=h_fine, growth=0.15, width=20.0, height=20.0, h=4.0,
                           n_steps=2, output_dir=outdir, progress=False, formulation="p1")
    assert res["formulation"] == "p1"
    P, Ph = res["force"], res["hertz_force"]
    assert abs(res["bottom_reaction"] - P) <= 1e-5 * P
    assert 0.98 < P / Ph < 1.10, (P, Ph)
    assert abs(res["p_max"] / res["hertz_p_max"] - 1.0) < 0.06
    assert abs(res["contact_radius"] - res["hertz_contact_radius"]) <= h_fine
    assert res["penetration"] < 1e-3 * res["indentation"]
    if MPI.COMM_WORLD.rank == 0:
        assert os.path.getsize(res["png"]) > 10_000


def test_hertz_sphere_p1_ranks():
    """P1 displacement on all ranks and on one rank (same gmsh mesh): the same force and
    p_max to 1e-8 (serially the two runs coincide)."""
    kw = dict(h_fine=0.1, growth=0.3, width=10.0, height=10.0, h=3.0, n_steps=2,
              output_dir=None, progress=False, formulation="p1")
    r2 = hertz_sphere.run(comm=MPI.COMM_WORLD, **kw)
    r1 = hertz_sphere.run(comm=MPI.COMM_SELF, **kw)
    assert r1["active_nodes"] == r2["active_nodes"] > 3
    for key in ("force", "p_max", "contact_radius"):
        assert abs(r2[key] / r1[key] - 1.0) <= 1e-8, (key, r1[key], r2[key])


@pytest.mark.slow
def test_hertz_sphere_p1_accuracy():
    """Default sphere mesh (h_fine = 25 µm) in P1 displacement: the acceptance criteria of the
    mixed run — force within 3 %, p_max within 5 %, contact radius within one element
    (measured +2.8 %, +4.5 %)."""
    res = hertz_sphere.run(output_dir=None, picture=False, progress=False, formulation="p1")
    assert abs(res["force"] / res["hertz_force"] - 1.0) <= 0.03, res["force"]
    assert abs(res["p_max"] / res["hertz_p_max"] - 1.0) <= 0.05, res["p_max"]
    assert abs(res["contact_radius"] - res["hertz_contact_radius"]) <= res["h_fine"]
    assert abs(res["bottom_reaction"] - res["force"]) <= 1e-5 * res["force"]
