"""Hertz sphere with a coarse faceted sphere tool (issue 4): the Nagata-smoothed tool gives p_max
within 5 % of the analytic-tool result on the same block mesh, flat facets are reported for
comparison; faceted (Nagata) sphere contact on 2 ranks equals the serial run; deterministic
Nagata patch choice on shared patch edges."""

import math

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact, penalty_from_beta
from fxcontact.materials import LinearElastic
from fxcontact.meshing import BLOCK_TAGS, block
from fxcontact.processes import hertz, hertz_sphere
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools.faceted import FacetedTool

from helpers import gather_by_position

# small block mesh of tests/test_hertz.py::test_hertz_sphere_small (5 nodes on a, 20 mm block)
SMALL = dict(h_fine=0.05, growth=0.3, width=20.0, height=20.0, h=4.0, n_steps=2,
             output_dir=None, picture=False, progress=False)


def test_octahedral_sphere_tool_mesh():
    """The Hertz sphere's tool mesh: closed, outward, vertices on the sphere, mirror-symmetric about
    x = 0 and y = 0 (needed by the quarter model), lowest vertex at the first-touch point with
    edges of the requested length there."""
    R = 5.0
    n = hertz.octahedral_divisions(R, 1.0)
    assert n == 8
    V, T = hertz.octahedral_sphere(n, R, (0.0, 0.0, R))
    assert V.shape == (4 * n * n + 2, 3) and T.shape == (8 * n * n, 3)
    tool = FacetedTool(V, T, mode="flat")  # checks orientation and closedness
    assert tool.closed
    assert np.allclose(np.linalg.norm(V - [0.0, 0.0, R], axis=1), R, atol=1e-12)
    keys = {tuple(k) for k in np.round(V, 9)}
    for ax in (0, 1):
        W = V.copy()
        W[:, ax] *= -1.0
        assert all(tuple(k) in keys for k in np.round(W, 9))
    low = int(np.argmin(V[:, 2]))
    assert np.allclose(V[low], 0.0, atol=1e-12)
    nb = np.unique(T[np.any(T == low, axis=1)])
    nb = nb[nb != low]
    assert len(nb) == 4
    edge = np.linalg.norm(V[nb] - V[low], axis=1)
    assert np.allclose(edge, 2 * R * math.sin(math.pi / (4 * n)), rtol=1e-12)
    assert abs(edge[0] - 1.0) < 0.05


def test_nagata_patch_choice_on_shared_edge_is_deterministic():
    """Points on the symmetry plane x = 0 project on the patch edge shared by two mirror-image
    patches: a tie. The chosen patch must not depend on round-off (the implicit schemes require
    unchanged projected patches to declare convergence; with a distance tie-break 542 of 1600
    projections below flipped patch under 1e-15 relative perturbations, doubling the Newton
    iterations of the faceted Hertz run)."""
    V, T = hertz.octahedral_sphere(8, 5.0, (0.0, 0.0, 5.0))
    tool = FacetedTool(V, T, mode="nagata")
    rng = np.random.default_rng(0)
    y = np.linspace(0.02, 0.4, 20)
    for z in (-2e-4, -1e-6, 1e-6, 1e-3):
        P = np.c_[np.zeros_like(y), y, z + y**2 / 10.0]
        base = tool.project(P)
        assert np.all(base.flag == 0)
        for _ in range(20):
            pr = tool.project(P * (1.0 + 1e-15 * rng.standard_normal(P.shape)))
            assert np.array_equal(pr.feature, base.feature), z
            assert np.allclose(pr.gap, base.gap, rtol=0.0, atol=1e-12)


@pytest.mark.slow
def test_hertz_faceted_sphere_nagata_vs_analytic(record_property):
    """Issue 4 acceptance: coarse faceted sphere (edges 0.98 mm at the lowest vertex ≈ 3.8 a,
    512 triangles, NVV normals) on the same block mesh as the analytic sphere. Nagata: p_max
    within 5 % of the analytic-tool p_max (measured −0.19 %), force within 3 % (+0.27 %),
    contact radius within one element, no fallbacks, no extra Newton iterations.

    Flat facets (reported): the 4 facets around the lowest vertex form a shallow pyramid
    (slopes 0.10–0.14), i.e. a conical indenter, P ≈ (2/π) E* δ²/tanβ ≈ 180–250 N against
    ≈ 1000 N, with a pressure peak at the tip. Measured: P = 237 N (−78 % against the analytic
    tool), p_max = 4.6 p0. Asserted only that flat facets fail the 5 % criterion and carry less
    than half of the analytic load."""
    res = hertz_sphere.compare_tools(**SMALL)
    an, na, fl = res["analytic"], res["nagata"], res["flat"]
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res["table"])
    for kind in hertz.TOOLS:
        r = res[kind]
        for k in ("force", "p_max", "contact_radius", "fallbacks", "newton_iterations"):
            record_property(f"{kind}_{k}", r[k])
    # same block mesh, same Hertz reference
    assert na["cells"] == an["cells"] == fl["cells"]
    assert na["hertz_p_max"] == an["hertz_p_max"]
    for r in (an, na, fl):
        assert abs(r["bottom_reaction"] - r["force"]) <= 1e-5 * r["force"]
    assert na["tool_triangles"] == 512 and na["tool_facet_size"] > 3.0 * an["contact_radius"]
    # Nagata against the analytic sphere
    assert abs(na["p_max"] / an["p_max"] - 1.0) <= 0.05, (na["p_max"], an["p_max"])
    assert abs(na["force"] / an["force"] - 1.0) <= 0.03, (na["force"], an["force"])
    assert abs(na["contact_radius"] - an["contact_radius"]) <= SMALL["h_fine"]
    assert na["fallbacks"] == 0 and na["tool_projection_fallbacks"] == 0
    assert na["newton_iterations"] <= an["newton_iterations"] + len(na["history"])
    # flat facets: reported; they fail the criterion by a wide margin
    assert abs(fl["p_max"] / an["p_max"] - 1.0) > 0.05
    assert fl["force"] < 0.5 * an["force"]


# ------------------------------------------------------------------ 1 rank vs 2 ranks

def _pressed_block(comm, n_inc=2):
    """Elastic block [-1, 1]² × [-0.8, 0] (clamped bottom) pressed 30 µm by a Nagata faceted
    sphere (R = 5, 0.98 mm edges) whose lowest vertex touches the top face off-centre, at
    (0.11, −0.07, 0): the contact zone (a ≈ 0.39) spans several patches and, on 2 ranks, the
    partition boundary."""
    msh, _, ft = block(comm, [-1.0, -1.0, -0.8], [1.0, 1.0, 0.0], 0.15)
    sp = MixedSpace(msh)
    mat = LinearElastic(2e5, 0.3)
    sim = Simulation(sp, mat, progress=False)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["zmin"]), np.zeros(3))
    t_end, dt, delta, R = 1.0, 1.0 / n_inc, 0.03, 5.0
    V, T = hertz.octahedral_sphere(8, R, (0.11, -0.07, R))
    tool = FacetedTool(V, T, mode="nagata", velocity=(0.0, 0.0, -delta / t_end), name="ball")
    c = sim.add_contributor(NodalContact(
        ContactBoundary(sp, ft, BLOCK_TAGS["zmax"]), tool, scheme="implicit",
        penalty=penalty_from_beta(mat, 1e4, 0.15, dt=dt), element_size=0.15))
    sim.run(t_end, dt)
    return sim, c


def test_faceted_sphere_contact_parallel_matches_serial():
    comm = MPI.COMM_WORLD
    out = []
    for cm in (comm, MPI.COMM_SELF):
        sim, con = _pressed_block(cm)
        sp = sim.space
        own = sp.vertex_owned
        x, v = gather_by_position(cm, sim._x_ref[sp.vertex_geometry][own],
                                  sim.w.x.array[sp.vertex_dofs[own]])
        b = con.boundary
        xb = sim._x_ref[sp.vertex_geometry][b.vertices]
        xp, p = gather_by_position(cm, xb, con.pressures())
        out.append((x, v, xp, p, sim.history[-1]))
    (x1, v1, xp1, p1, h1), (x2, v2, xp2, p2, h2) = out
    assert h2["contact_nodes"] >= 15 and h2["contact_fallbacks"] == 0
    assert np.allclose(x1, x2, atol=1e-12) and np.allclose(xp1, xp2, atol=1e-12)
    assert np.max(np.abs(v1 - v2)) <= 1e-8 * np.max(np.abs(v2))
    assert np.max(np.abs(p1 - p2)) <= 1e-8 * np.max(p2)
    for k in ("ball_force_x", "ball_force_y", "ball_force_z", "contact_area", "contact_nodes",
              "contact_penetration_true", "contact_penetration_predicted",
              "contact_pressure_max"):
        assert abs(h1[k] - h2[k]) <= 1e-8 * max(abs(h2[k]), 1e-30), (k, h1[k], h2[k])
