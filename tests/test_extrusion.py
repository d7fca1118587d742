"""Forward extrusion (``fxcontact.processes.extrusion``) at the reduced size of
``ExtrusionCase.quick()``: R₀ 5 → 3.5 mm through a 20° die, h = 1 mm, one quarter, Tresca
friction on the die and the container.

Checked: the steady punch pressure lies between the ideal work and 1.1 × (Avitzur's die bound
+ the container friction 2 m̄ k L_c/R₀), for this die and another angle and reduction (30°,
R₁ = 4 mm: 36 % instead of 51 %); with k given in the container's law, the container's
force equals 2 m̄ k L_c/R₀ × A₀ within 3 %; volume, element quality and the power balance; the
container and the die as two tools of one contact give the answer of one profile, but for a node
less than its depth past the container's end (measured below the bore continued, not the die's
entry fillet); 1 vs 2 ranks.
Both angles with both reductions: ``benchmarks/bench_extrusion.py``."""

import numpy as np
import pytest
from mpi4py import MPI

import dolfinx.mesh

from fxcontact.meshing import DRAWING_BAR_TAGS
from fxcontact.processes import ExtrusionCase, build_extrusion, extrusion, run_extrusion


@pytest.fixture(scope="module")
def given_k():
    """The quick case to steady state with the container's k given: σ₀/√3 at the die's rate."""
    k = ExtrusionCase.quick().theory()["shear_yield"]
    res = run_extrusion(ExtrusionCase.quick(container_shear_limit=k), pictures=False)
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res.report())
    return res


@pytest.fixture(scope="module")
def other_die():
    """Another die angle and reduction to steady state (k from the local strain rate)."""
    res = run_extrusion(ExtrusionCase.quick(alpha=30.0, R1=4.0), pictures=False)
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res.report())
    return res


def _band(res):
    assert res.status == "completed", res.message
    assert res.punch_pressure is not None, "no steady state"
    th = res.theory
    assert th["ideal"] < res.punch_pressure < 1.1 * th["upper"], (res.punch_pressure, th)
    assert th["ideal"] < res.die_pressure < 1.1 * th["avitzur"]
    assert res.max_volume_change < 5e-3
    assert res.min_quality > 0.1
    # the punch's power = plastic dissipation + friction, to the discretisation error (the
    # penalty work oscillates as nodes enter the die); with the penalty work, the discrete
    # virtual-power identity (the punch force includes the friction on the punched face's rim)
    assert abs(res.power_balance) < 0.05, res.power_balance
    assert abs(res.power_balance_penalty) < 1e-6, res.power_balance_penalty


@pytest.mark.serial   # a run to steady state; the MPI path: test_one_and_two_ranks_agree
@pytest.mark.slow
def test_punch_pressure_in_band(given_k):
    _band(given_k)


@pytest.mark.serial
@pytest.mark.slow
def test_other_angle_and_reduction_in_band(other_die):
    _band(other_die)
    th = other_die.theory
    assert th["reduction"] == pytest.approx(1 - 0.8 ** 2)
    assert th["container"] > 0      # the container's share is part of the band


@pytest.mark.serial
@pytest.mark.slow
def test_container_force_with_given_k(given_k):
    """The billet slides rigidly in the container: with k fixed, its axial force is the
    Tresca stress m̄ k over the wall still in the container."""
    assert given_k.container_ratio == pytest.approx(1.0, abs=0.03)
    # the report says which k each friction law uses (the contact's line of the summary)
    text = given_k.report()
    assert "'container' Tresca(mbar=0.3), k = 46.07 given" in text, text
    assert "'die' Tresca(mbar=0.1), k of the material at each node's local strain rate" in text, text


def _histories_agree(a, b, keys, rtol=1e-8):
    assert len(a) == len(b)
    for qa, qb in zip(a, b):
        for k in keys:
            assert abs(qa[k] - qb[k]) <= rtol * abs(qb[k]), (k, qa[k], qb[k])
        assert qa["contact_nodes"] == qb["contact_nodes"]


def _gaps_at(s, dz, dp, phi=0.7):
    """Signed gaps (mm) of the two descriptions of ``s`` (a "separate" set-up) at the point
    ``dz`` past the container's end and ``dp`` outside the bore (``dp > 0``: inside the tools):
    the smallest gap over the container and the die, and the one profile's gap."""
    r, z = s.case.R0 + dp, s.corner + dz
    X = np.array([[r * np.cos(phi), r * np.sin(phi), z]])
    return (min(float(t.project(X, 0.0).gap[0]) for t in s.tools),
            float(s.profile.project(X, 0.0).gap[0]))


def test_separate_tools_gap_at_the_container_end():
    """The container and the die as two tools (the smallest gap of the two) measure a point
    as the one profile of both does — outside the tools, and inside them upstream of the
    container's end or more than its depth p past it — but not a point less than p past the
    container's end: there the die's entry face (inside the union of the two bodies) is nearer
    than its fillet, so the die's gap is above the container's, and the container's bore
    continued past its end gives −p where the profile gives the depth below the fillet of radius
    R_f, −(√(δ² + (R_f + p)²) − R_f): shallower by about δ²/2(R_f + p)."""
    s = build_extrusion(ExtrusionCase.quick(container="separate", mbar_container=0.1))
    assert [t.name for t in s.tools] == ["container", "die"]
    Rf = s.case.entry_fillet
    for dz, dp in ((-1e-3, 7.5e-4), (-1e-4, 7.5e-4), (8e-4, 7.5e-4), (2e-3, 7.5e-4),
                   (0.3, 0.0), (5e-4, -1e-3), (-5e-4, -1e-3), (0.1, -0.2)):
        two, one = _gaps_at(s, dz, dp)
        assert abs(two - one) <= 1e-14, (dz, dp, two, one)
    for dz, dp in ((2e-4, 7.5e-4), (7e-4, 7.5e-4), (1e-3, 2e-3)):
        two, one = _gaps_at(s, dz, dp)
        assert two == pytest.approx(-dp, abs=1e-14)
        assert one == pytest.approx(-(np.hypot(dz, Rf + dp) - Rf), abs=1e-14)
        assert two - one == pytest.approx(dz ** 2 / (2 * (Rf + dp)), rel=1e-2)


def _watch_container_end(s, seen: list):
    """Append to ``seen``, at every evaluation of the contact of the set-up ``s`` (Newton
    iterates and line-search trials), the number of penetrated nodes less than their depth past
    the container's end (where the two tool descriptions differ:
    test_separate_tools_gap_at_the_container_end)."""
    contact = s.contact
    evaluate = contact.evaluate

    def watched(w, jacobian):
        terms = evaluate(w, jacobian)
        n = contact.nodes
        past = n.positions[:, 2] - s.corner
        seen.append(int(np.sum((past > 0.0) & (past < -n.gap))))
        return terms

    contact.evaluate = watched
    return s


@pytest.mark.serial
def test_separate_tools_equal_one_profile(monkeypatch):
    """A container and a die as two tools of one contact (each node takes the tool with the
    smallest gap) give the history of one profile of both, Newton iterations included, as long
    as no node comes less than its depth p past the container's end, checked at every
    evaluation: there the two descriptions differ by about δ²/2(R_f + p)
    (test_separate_tools_gap_at_the_container_end). With dt = 0.025 the second increment is cut
    back (here) and the third ends with a node δ = 7.2e-4 mm past it at p = 7.5e-4 mm: gaps
    5e-7 mm apart, punch forces 2e-5. With dt = 0.0125 (6 increments) no node comes there."""
    seen = {}

    def build_watched(case, *args, **kwargs):
        seen[case.container] = []
        return _watch_container_end(build_extrusion(case, *args, **kwargs),
                                    seen[case.container])

    monkeypatch.setattr(extrusion, "build", build_watched)
    runs = [run_extrusion(ExtrusionCase.quick(container=c, mbar_container=0.1, t_end=0.075,
                                              dt=0.0125, stop_at_steady=False), pictures=False)
            for c in ("separate", "profile")]
    for c, counts in seen.items():
        assert counts and not any(counts), \
            f"{c}: a penetrated node less than its depth past the container's end"
    assert len(runs[0].history) == 6
    _histories_agree(runs[0].history, runs[1].history, ("punch_force", "penetration"))
    assert [q["newton_iterations"] for q in runs[0].history] == \
        [q["newton_iterations"] for q in runs[1].history]


def test_one_and_two_ranks_agree():
    """Three increments on all ranks and on COMM_SELF agree to 1e-8 (meaningful under
    ``mpirun -n 2``)."""
    if MPI.COMM_WORLD.size == 1:
        pytest.skip("compares the ranks of COMM_WORLD with one rank: run under mpirun -n 2")
    case = ExtrusionCase.quick(t_end=3 * ExtrusionCase.quick().dt, stop_at_steady=False)
    a, b = (run_extrusion(case, comm=c, pictures=False).history
            for c in (MPI.COMM_WORLD, MPI.COMM_SELF))
    assert len(a) == 3
    _histories_agree(a, b, ("punch_force", "container_force", "dissipation"))
    for qa, qb in zip(a, b):
        assert abs(qa["volume_change"] - qb["volume_change"]) <= 1e-11


def test_bad_case():
    with pytest.raises(ValueError, match="R1"):
        ExtrusionCase.quick(R1=6.0)
    with pytest.raises(ValueError, match="alpha"):
        ExtrusionCase.quick(alpha=90.0)
    with pytest.raises(ValueError, match="mbar_container"):
        ExtrusionCase.quick(mbar_container=1.5)
    with pytest.raises(ValueError, match="one friction law"):
        ExtrusionCase.quick(container="profile", mbar_container=0.3, mbar_die=0.1)
    with pytest.raises(ValueError, match="container must be"):
        ExtrusionCase.quick(container="cylinder")
    with pytest.raises(ValueError, match="container_shear_limit"):
        ExtrusionCase.quick(container_shear_limit=-1.0)
    with pytest.raises(ValueError, match="too short"):
        ExtrusionCase.quick(length=6.0)


def test_quick_on_the_class_and_on_a_case():
    """``quick`` on the class starts from the default case; on a case (as the rolling cases'
    ``case.quick()``) it keeps the case's other fields instead of dropping them."""
    from fxcontact import Tresca
    from fxcontact.processes import DrawingCase, UpsettingCase

    for cls, field, value in ((ExtrusionCase, "alpha", 30.0), (DrawingCase, "alpha", 15.0),
                              (UpsettingCase, "friction", Tresca(0.3))):
        case = cls(**{field: value})
        q = case.quick()
        assert getattr(q, field) == value
        assert q == cls.quick(**{field: value}) == cls(**{**cls.QUICK, field: value})
        assert all(getattr(q, k) == v for k, v in cls.QUICK.items())
        assert case.quick(h=2.0).h == 2.0
    with pytest.raises(ValueError, match="R1"):        # checked: R1 6 > QUICK's R0 5
        ExtrusionCase(alpha=30.0).quick(R1=6.0)


@pytest.mark.slow
def test_punch_reaction_takes_the_rim_contact():
    """The punched face's rim nodes are under the punch's velocity condition and slide on the
    container (contact with friction): the punch's reaction (``Simulation.add_reaction``)
    takes their contact forces, so it balances the contact's forces on the container and the
    die, summed independently over all the contact nodes, to Newton's tolerance (the symmetry
    planes carry no axial force). The rim's share is far above that tolerance."""
    case = ExtrusionCase.quick(container="separate", mbar_container=0.1)
    s = build_extrusion(case)
    msh, ct = s.sim.mesh, s.contact
    back = s.sim.facets(s.facet_tags, DRAWING_BAR_TAGS["back"])
    verts = dolfinx.mesh.compute_incident_entities(msh, back, msh.topology.dim - 1, 0)
    rim = np.isin(ct.boundary.vertices, verts)
    comm = s.sim.comm
    for _ in range(2):
        q = s.sim.step(case.dt).row
        forces = sum(q[f"{t.name}_force_z"] for t in s.tools)      # on the tools
        on_rim = comm.allreduce(float(np.sum((ct._r + ct._rf)[rim & (ct._h > 0), 2])),
                                op=MPI.SUM)
        assert abs(on_rim) > 1e-4 * abs(forces), on_rim
        assert q["punch_z"] == pytest.approx(forces, rel=1e-6), (q["punch_z"], forces)
    s.sim.close()
