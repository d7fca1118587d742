"""Remeshing inside a Simulation (Simulation.remesh, set_remeshing): a quarter billet upset by a
flat die with Tresca friction, a symmetry plane, velocity conditions and a reaction, remeshed
in the middle of the run. Serial and on 2 ranks.

The new mesh depends on the last bits of the deformed boundary (gmsh), which differ between
1 and 2 ranks at round-off: a remeshed run agrees between them to discretisation accuracy, not
to round-off (the runs below compare each run with its own unremeshed twin).
"""

import csv
import os

import numpy as np
import pytest
from mpi4py import MPI

import fxcontact as fx
from fxcontact.remesh.criteria import RemeshCriteria

from helpers import shared_tmpdir

COMM = MPI.COMM_WORLD
DT = 0.06
H = 2.2          # the remesh size: about the billet's own mean edge length


def _setup(output_dir=None, overwrite=True, **kw):
    msh, _, ft = fx.cylinder_billet(COMM, radius=10.0, height=15.0, h=3.0)
    space = fx.MixedSpace(msh)
    sim = fx.Simulation(space, fx.NortonHoff(K=50.0, m=0.15), output_dir=output_dir,
                        name="upset", progress=False, overwrite=overwrite, **kw)
    f = {k: sim.facets(ft, v) for k, v in fx.BILLET_TAGS.items()}
    sim.add_velocity_bc(f["symmetry_x"], 0.0, component=0)
    sim.add_symmetry_plane(f["symmetry_y"], (0, 1, 0), name="sym_y")
    sim.add_velocity_bc(f["bottom"], 0.0, component=2)
    sim.add_reaction("bottom", f["bottom"])
    die = fx.Plane(point=(0, 0, 15.0), normal=(0, 0, -1), velocity=(0, 0, -5.0), name="die")
    contact = fx.NodalContact(fx.ContactBoundary(space, ft, fx.BILLET_TAGS["top"]), die,
                              friction=fx.Tresca(0.3))
    sim.add_contributor(contact)
    return sim, ft, contact


def _tags(ft):
    return set(v for vs in COMM.allgather(np.unique(ft.values).tolist()) for v in vs)


@pytest.fixture(scope="module")
def runs():
    """The same run without and with a remesh after increment 3 (outputs of the second)."""
    plain, _, _ = _setup()
    for _ in range(5):
        plain.step(DT)
    out = shared_tmpdir("fxc_remesh_")
    sim, ft, contact = _setup(out)
    for _ in range(3):
        sim.step(DT)
    rec = sim.remesh(size=H)
    for _ in range(2):
        sim.step(DT)
    sim.close()
    return plain, sim, ft, contact, rec, out


def test_next_increment_as_without_remesh(runs):
    """The increment after the remesh (and the one after it) as without the remesh, to the
    discretisation accuracy: the die force within 1 % (measured 0.04 %: the new mesh of the
    same size changes the discretisation, the state carried over is the same), the bottom
    reaction and the symmetry plane's force (a tenth of the die force) within 1 % of the die
    force, the die in contact with as many nodes per area (same penetration to 20 %)."""
    plain, sim, _, _, _, _ = runs
    for k in (3, 4):
        a, b = plain.history[k], sim.history[k]
        F = abs(a["die_force_z"])
        assert b["remesh"] == 1
        assert abs(b["die_force_z"] - a["die_force_z"]) < 0.01 * F
        assert abs(b["bottom_z"] - a["bottom_z"]) < 0.01 * F
        assert abs(b["sym_y_y"] - a["sym_y_y"]) < 0.01 * F
        assert b["contact_nodes"] > 0
        assert abs(b["contact_penetration_true"] / a["contact_penetration_true"] - 1) < 0.2
        assert b["newton_iterations"] <= a["newton_iterations"] + 3


def test_volume_tags_and_history(runs):
    """The remesh changes the volume by ≤ 0.05 %; every tag of the old boundary is on the new
    one; the history has the remesh count; the CSV its column; the VTK series a new piece."""
    plain, sim, ft, contact, rec, out = runs
    assert abs(rec.volume_change) <= 5e-4
    assert rec.cells_before > 0 and rec.cells_after > 0
    assert _tags(sim._remesh_facet_tags) == _tags(ft) == set(fx.BILLET_TAGS.values())
    assert [r["remesh"] for r in sim.history] == [0, 0, 0, 1, 1]
    assert sim.remeshes == [rec] and "remesh 1 at t = 0.18" in rec.line()
    # the contact and the conditions act on the new mesh
    assert contact.boundary.mesh is sim.mesh
    if COMM.rank == 0:
        with open(os.path.join(out, "upset_history.csv")) as fh:
            rows = list(csv.DictReader(fh))
        assert [int(r["remesh"]) for r in rows] == [0, 0, 0, 1, 1]
        files = [f for _, f in fx.io.read_pvd(os.path.join(out, "upset.pvd"))]
        assert len(files) == 6 and files[3].startswith("upset0") \
            and files[4].startswith("upset_r1")


@pytest.mark.slow
def test_checkpoint_after_remesh_resumes(runs):
    """A checkpoint written after a remesh, resumed from the set-up on the initial mesh, gives
    the same next increment as the run that wrote it (to round-off)."""
    out = shared_tmpdir("fxc_remesh_ckpt_")
    sim, _, _ = _setup(out)
    for _ in range(3):
        sim.step(DT)
    sim.remesh(size=H)
    sim.step(DT)
    path = sim.write_checkpoint()
    sim.step(DT)
    sim.close()
    again, _, _ = _setup(out, overwrite=False)
    again.resume(path)
    assert len(again.remeshes) == 1 and again.increment == 4
    again.step(DT)
    again.close()
    a, b = sim.history[-1], again.history[-1]
    F = abs(a["die_force_z"])
    for k in ("die_force_z", "bottom_z", "sym_y_y"):
        assert abs(a[k] - b[k]) < 1e-8 * F
    assert abs(a["volume_change"] - b["volume_change"]) < 1e-12
    assert b["remesh"] == 1


def test_automatic_remesh_by_criterion():
    """set_remeshing: a criterion that fires remeshes after the increment; a new mesh poorer
    than the threshold does not call again at once."""
    sim, _, _ = _setup()
    sim.set_remeshing(RemeshCriteria(min_quality=0.9, min_volume_ratio=None), size=H)
    for _ in range(3):
        sim.step(DT)
    assert sim.remeshes and "min quality" in sim.remeshes[0].reason
    assert len(sim.remeshes) < 3
    assert sim.history[-1]["remesh"] == len(sim.remeshes) or \
        sim.history[-1]["remesh"] == len(sim.remeshes) - 1
    assert sim.history[-1]["contact_nodes"] > 0


def test_misuse():
    """Bad settings, and a facet array that cannot be re-selected on a new mesh (an array of
    a selection: built by hand), refused on every rank naming the call and the fix."""
    sim, ft, _ = _setup()
    with pytest.raises(ValueError, match="size"):
        sim.set_remeshing(size=-1.0)
    with pytest.raises(ValueError, match="RemeshCriteria"):
        sim.set_remeshing(criteria={"min_quality": 0.2})
    with pytest.raises(ValueError, match="SizeZone"):
        sim.set_remeshing(zones=[1.0])
    sel = sim.facets(ft, fx.BILLET_TAGS["lateral"])
    sim.add_reaction("side", np.array(sel))
    with pytest.raises(ValueError, match=r"add_reaction\(\) call #4 \('side'\).*sim.facets"):
        sim.remesh(size=H)


def test_contributor_without_remesh_refused():
    sim, ft, _ = _setup()

    class Still:
        def evaluate(self, w, jacobian):
            from fxcontact.newton.problem import NodalTerms
            return NodalTerms.empty(3)

        def stable(self):
            return True

    sim.add_contributor(Still())
    with pytest.raises(ValueError, match="Still.*remesh\\(space, facet_tags\\)"):
        sim.remesh(size=H)


def test_controller_without_remesh_refused():
    """A controller may keep something of the mesh (a surface, vectors of the system): one
    without remesh(space, facet_tags) stops a remesh on every rank, naming it; a bad
    RemeshCriteria.every is refused by set_remeshing."""
    sim, _, _ = _setup()

    class Counter:
        def begin_increment(self, sim, t, dt, x_t):
            pass

    sim.add_controller(Counter())
    with pytest.raises(ValueError, match=r"controller\(s\) \['Counter'\].*remesh\(space, "
                                         r"facet_tags\)"):
        sim.remesh(size=H)
    with pytest.raises(ValueError, match="every must be an integer >= 1"):
        sim.set_remeshing(RemeshCriteria(every=0))


@pytest.mark.slow
def test_extrusion_through_a_wide_die_with_remeshing():
    """The reduced extrusion through a 45° die: without remeshing an entry element inverts
    after 1 mm of punch stroke (benchmarks/bench_remesh_extrusion.py); with remeshing the run
    completes 2 mm, the punch pressure jumps at a remesh by no more than between two
    increments before it, the volume changes by less than 0.5 %."""
    from fxcontact.processes import ExtrusionCase, run_extrusion
    case = ExtrusionCase.quick(alpha=45.0, stop_at_steady=False, t_end=0.2, remesh=True)
    res = run_extrusion(case, COMM, pictures=False)
    rows = res.history
    assert res.status == "completed" and rows[-1]["remesh"] >= 1
    assert max(abs(q["volume_change"]) for q in rows) < 5e-3
    p = [q["punch_pressure"] for q in rows]
    after = [i for i in range(4, len(rows)) if rows[i]["remesh"] != rows[i - 1]["remesh"]]
    assert after
    for i in after:
        before = max(abs(a - b) for a, b in zip(p[i - 3: i], p[i - 4: i - 1]))
        assert abs(p[i] - p[i - 1]) <= max(before, 0.05 * p[i - 1])
    # the power balance follows the new meshes: the discrete identity (penalty work included)
    # to round-off at every increment not ended by a remesh, the first on a new mesh included
    kept = [q for q, nxt in zip(rows, rows[1:] + [None])
            if nxt is None or nxt["remesh"] == q["remesh"]][1:]
    assert any(q["remesh"] >= 1 for q in kept)
    assert max(abs(q["power_balance_penalty"]) for q in kept) < 1e-6


@pytest.mark.slow
def test_rescue_remesh_before_an_inverting_increment_fails():
    """The 45° extrusion with one cut-back allowed and no criterion: at t = 0.1 an entry cell
    (quality 0.02) inverts at dt and at dt/2; the rescue remeshes once, takes the increment
    again from dt on the new mesh, and the run goes on (without the rescue it stops there
    with a MeshInversionError: benchmarks/bench_remesh_extrusion.py)."""
    from fxcontact.processes import ExtrusionCase
    from fxcontact.processes.extrusion import build
    case = ExtrusionCase.quick(alpha=45.0, stop_at_steady=False)
    sim = build(case, COMM, None, 0).sim
    sim.set_remeshing(criteria=None, size=case.h)
    while sim.t < 0.125 - 1e-9:
        sim.step(case.dt, max_cutbacks=1)
    assert [r.reason for r in sim.remeshes] == ["an element would invert"]
    rec = sim.remeshes[0]
    assert rec.increment == sim.increment - 1 and rec.min_quality_after > 0.3
    # the increment after the remesh is the one that inverted, taken again from dt
    row = sim.history[rec.increment]
    assert row["remesh"] == 1 and row["dt"] == case.dt and row["min_quality"] > 0.3
    assert abs(row["volume_change"]) < 5e-3


@pytest.mark.slow
def test_contact_coverage_criterion_refines_the_bite():
    """min_elements_across: the die's contact on the coarse billet is spanned by about 5
    elements; with a threshold of 8 the first increment calls a remesh, whose zone of size H/3
    under the die spans it by about 12: no further remesh in the next increments."""
    from fxcontact.remesh.volume import SizeZone
    sim, _, _ = _setup()
    zone = SizeZone(h=H / 3, box=([0.0, 0.0, 12.0], [12.0, 12.0, 16.0]))
    sim.set_remeshing(RemeshCriteria(min_quality=None, min_volume_ratio=None,
                                     min_elements_across=8.0), size=H, zones=[zone])
    for _ in range(3):
        sim.step(DT)
    assert len(sim.remeshes) == 1
    assert sim.remeshes[0].increment == 1
    assert "contact 'die' spanned by" in sim.remeshes[0].reason
    assert sim.remeshes[0].cells_after > 2 * sim.remeshes[0].cells_before
    assert [r["remesh"] for r in sim.history] == [0, 1, 1]
    assert sim.history[-1]["contact_nodes"] > 0


def _ring_case(**kw):
    import dataclasses
    from fxcontact.processes import ring_rolling as rr
    return dataclasses.replace(rr.RingRollingCase().quick(), remesh=True, **kw)


@pytest.mark.slow
def test_ring_remesh_refines_in_front_of_the_bite():
    """BiteZones: a remesh of the rolled ring is finer (the zone's size h_theta) over the arc
    in front of the bite than on the opposite side (the mean edge length there); the
    centring's outer surface and the contact are on the new mesh."""
    from fxcontact.processes import ring_rolling as rr
    s = rr.build(_ring_case(remesh_arc=60.0), COMM)
    sim = s.sim
    sim.step(s.dt)
    sim.remesh()
    assert s.centring.outer.mesh is sim.mesh and s.contact.boundary.mesh is sim.mesh
    X = sim.vertex_positions()[sim._mesh_health._c2v_owned]
    theta = np.degrees(np.arctan2(X[:, :, 1].mean(axis=1), X[:, :, 0].mean(axis=1)))
    edges = np.mean([np.linalg.norm(X[:, i] - X[:, j], axis=1)
                     for i in range(4) for j in range(i + 1, 4)], axis=0)
    # the ring turns counterclockwise: the arc in front of the bite is at -60° < theta < 0
    sums = [COMM.allreduce(np.array([np.sum(edges[m]), np.sum(m)]), op=MPI.SUM)
            for m in ((theta > -55.0) & (theta < -5.0), np.abs(theta) > 120.0)]
    front, back = (a / n for a, n in sums)
    assert front < 0.7 * back
    assert front < 1.5 * s.h_theta


@pytest.mark.slow
def test_ring_rolling_with_remeshing():
    """RingRollingCase(remesh=True) over 0.3 revolution, remeshed every 4 increments (3/4 of
    a 40° arc): the run goes on across the remeshes (centring, idle mandrel, measures on
    each new mesh), the volume is kept, and the main roll's force and the mandrel's speed are
    continuous at a remesh. This coarse ring (1.4 elements across the bite) changes its force
    at the three remeshes by 3.3, 3.2 and 1.2 % (the same new meshes on 1 and 2 ranks), while
    between two increments on one mesh it changes by 2–19 % in this bite-in: a remesh moves it
    by at most 10 %. (Before ``fxcontact.remesh.topology`` gmsh gave a different new mesh each
    time for the same boundary, and the force after the first remesh varied by 25 % from run to
    run: 37.5k, 43.2k, 44.2k, 37.5k N after 42.0k.)

    The power identity (tools = dissipation + friction + penalty work) holds across the
    remeshes to Newton's tolerance, as without them (tests/test_ring_rolling.py): its error is
    the final Newton residual tested with the velocity. With ``newton_rtol`` 1e-9 an increment
    ends anywhere below 1e-9 of its first residual (the final residual 2e-6 to 9e-4 here) and
    the identity reached 1.2e-5 (3.2e-4 once on 2 ranks, in an earlier run with a cut-back, not
    reproduced since); with 1e-11 (one Newton iteration more) every increment ends at the
    round-off floor (~1e-6) and it holds to 2e-8 on 1 and 2 ranks: bounded by 1e-6 here."""
    from fxcontact.processes import ring_rolling as rr
    res = rr.run(_ring_case(revolutions=0.3, remesh_arc=40.0, newton_rtol=1e-11), COMM,
                 pictures=False)
    rows = res.history
    assert res.status == "done" and res.revolutions > 0.29
    assert len(res.remeshes) >= 2
    assert all("increments since the last remesh" in r.reason for r in res.remeshes)
    assert abs(rows[-1]["volume_change"]) < 1e-3
    counts = [q["remesh"] for q in res.sim_history]
    jumps = [i for i in range(3, len(rows)) if counts[i] != counts[i - 1]]
    assert jumps
    for i in jumps:
        F = [abs(q["main_force_x"]) for q in rows[i - 1: i + 1]]
        assert abs(F[1] - F[0]) <= 0.1 * F[0], (i, F)
        assert abs(rows[i]["mandrel_omega"] / rows[i - 1]["mandrel_omega"] - 1) < 0.1
    # one power balance over the remeshes: NaN at the increments ended by a remesh (their start
    # configuration on the new mesh is not known under the cylindrical update), the discrete
    # identity with the penalty work elsewhere, the first increments on a new mesh included
    ended = [i for i in range(len(rows) - 1) if counts[i + 1] != counts[i]]
    assert ended and all(np.isnan(rows[i]["power_balance_penalty"]) for i in ended)
    # and what the tools delivered (the contact was reset by the remesh), not 0
    assert all(np.isnan(rows[i]["power_in"]) and np.isnan(rows[i]["main_power"]) for i in ended)
    assert np.isfinite(res.power_in) and res.power_in > 0
    kept = [rows[i] for i in range(1, len(rows)) if i not in ended]
    assert any(counts[rows.index(q)] >= 1 for q in kept)
    worst = max(abs(q["power_balance_penalty"]) for q in kept)
    if COMM.rank == 0:
        change = [rows[i]["main_force_x"] / rows[i - 1]["main_force_x"] - 1 for i in jumps]
        print(f"\nforce changes at the remeshes {np.round(change, 4).tolist()}; power "
              f"identity max {worst:.1e}")
    assert worst < 1e-6


@pytest.mark.slow
def test_ring_bite_refinement_follows_the_bite():
    """RingRollingCase(remesh=True, remesh_min_across=3): the bite zones on the rolled surfaces
    (size L/3, L = √(2Δh/Σ) the bite's contact length of ring-rolling theory) are meshed before
    the first increment and again as the ring turns (every 4 increments here: 3/4 of the
    zone's 40° arc), or when a bite is spanned by fewer than 3 elements. A ring of half the
    quick one's height started with a steady bite (``initial_bite`` 0.5 mm per roll: the
    reduction Δh = 1 mm of one revolution), 0.3 revolution. Checked at every
    increment before its remesh check, by ``ring_mill.bite_coverage`` (the contact nodes' arc
    over the mean edge of the facets between them; not the criterion's measure):

    * each bite is spanned by at least 3 elements (measured 3.5–5.9);
    * its contact arc is at least L and at most 2.5 L (the nodes touch beyond the projected
      length of the theory by the penalty's depth and the material piled up at the entry:
      1.2–1.9 L measured);
    * the volume stays within 0.5 %;
    * the main roll's force is continuous across the remeshes: its change at a remesh, less the
      trend's change per increment (a straight line fitted to the force from the second
      increment on; the first presses the initial bite out), is of the size of the steady
      oscillation of this coarse ring (its nodes cross the bite in less than an increment):
      the range of the force about the trend at the increments not first on a new mesh. With
      3 remeshes against 11 such increments the largest of 3 changes exceeds that range now and
      then although both have the same size (over 5 revolutions, 126 remeshes, the largest
      change at a remesh 2.13 kN, between two increments on one mesh 2.22 kN:
      ``benchmarks/bench_remesh_ring.py``): the bound is 1.5 × the range. Measured: range 1.30
      kN (of 42 kN), remesh changes up to 0.80 kN on 1 rank; on 2 ranks (whose new meshes vary
      from run to run at round-off) ranges 1.05–1.33 kN, changes up to 1.09–1.36 kN."""
    from fxcontact.processes import ring_mill
    from fxcontact.processes import ring_rolling as rr
    case = _ring_case(remesh_min_across=3.0, remesh_arc=40.0, H=20.0, initial_bite=0.5,
                      revolutions=0.3)
    s = rr.build(case, COMM)
    sim = s.sim
    assert len(sim.remeshes) == 1 and sim.remeshes[0].increment == 0
    coverage = []
    check = sim._remeshing.after_increment

    def measured_then_checked(sim_):
        coverage.append(ring_mill.bite_coverage(sim_, s.contact, s.centring.center))
        check(sim_)
    sim._remeshing.after_increment = measured_then_checked
    for _ in range(s.n_increments):
        sim.step(s.dt)
    rows = sim.history
    L = ring_mill.bite_length(case)
    across = {k: [c[k][2] for c in coverage] for k in ("main_roll", "mandrel")}
    arcs = {k: [c[k][0] for c in coverage] for k in ("main_roll", "mandrel")}
    F = np.array([abs(q["main_roll_force_x"]) for q in rows])[1:]
    counts = np.array([q["remesh"] for q in rows])[1:]
    i = np.arange(len(F))
    slope, f0 = np.polyfit(i, F, 1)
    dev = F - (f0 + slope * i)
    first = np.r_[False, counts[1:] != counts[:-1]]      # the first increment on a new mesh
    band = np.ptp(dev[~first])
    jumps = np.abs(np.diff(F) - slope)[first[1:]]
    if COMM.rank == 0:
        print(f"\nL = {L:.2f} mm; remeshes after increments "
              f"{[r.increment for r in sim.remeshes]}, cells "
              f"{[r.cells_after for r in sim.remeshes]}")
        for k in across:
            print(f"{k}: across {np.round(across[k], 2).tolist()}, arcs / L "
                  f"{np.round(np.array(arcs[k]) / L, 2).tolist()}, criterion "
                  f"{[round(q.get(f'elements_across_{k}', 0), 2) for q in rows]}")
        print(f"force [kN] {np.round(2e-3 * F, 2).tolist()}; band {2e-3 * band:.2f}, jumps "
              f"{np.round(2e-3 * jumps, 2).tolist()}; volume change max "
              f"{max(abs(q['volume_change']) for q in rows):.1e}")
    assert len(rows) == s.n_increments and len(sim.remeshes) >= 3
    for k in across:
        assert min(across[k]) >= 3.0, (k, across[k])
        assert all(L <= a <= 2.5 * L for a in arcs[k]), (k, arcs[k], L)
    assert max(abs(q["volume_change"]) for q in rows) <= 5e-3
    assert first.any() and (~first).sum() >= 3
    assert np.all(jumps <= 1.5 * band), (jumps, band)
