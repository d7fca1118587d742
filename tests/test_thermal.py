"""Heat with the mechanics (THEORY §16.6): adiabatic homogeneous compression of a thermo-softening
hardening law against its ODE, friction heating of a block sliding on a plane, and the
coupling's bad input."""

import dataclasses
import os
import shutil

import numpy as np
import pytest
from mpi4py import MPI
from scipy.integrate import solve_ivp

import fxcontact as fx
from fxcontact.checkpoint import list_checkpoints
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Tresca
from fxcontact.contact.nodal import NodalContact
from fxcontact.contact.penalty import Penalty
from fxcontact.meshing import BILLET_TAGS, BLOCK_TAGS, block, cylinder_billet
from fxcontact.tools.analytic import Plane
from helpers import shared_tmpdir
from test_viscoplastic import compress, table_law


def test_adiabatic_compression_follows_the_ode():
    """THEORY §16 check: frictionless compression at constant speed of an insulated block with
    a hardening, thermo-softening table law: ρc dT/dt = η_q σ₀(ε̄, ε̄̇, T) ε̄̇, ε̄̇ = v/h. The
    discrete recurrence (state and temperature at the start of each increment, the plastic
    power of the increment) holds to 1e-8; T − T₀ and the force are within 0.5 % of the ODE's
    (solve_ivp) at every increment (the scheme is first order in dt: 1.6 % of T − T₀ at a 5×
    larger dt); the heat balance closes."""
    law = table_law()
    mat = fx.Viscoplastic(law, regularization=1e-6, temperature=150.0)
    rho_c, eta, T0 = 1.0, 0.9, 150.0
    v, h0, dt, n_inc = 0.45, 1.0, 0.005, 120   # first order in dt: 1.6 % of ΔT at dt = 0.025
    thermal = fx.ThermalMaterial(rho_c=rho_c, conductivity=30.0, taylor_quinney=eta)
    sims = {}

    def setup(sim):
        sims["heat"] = fx.WorkpieceHeat(sim, thermal, T0)
        sim.add_controller(sims["heat"])

    sim, V0, out = compress(MPI.COMM_WORLD, mat, v=v, h0=h0, dt=dt, n_inc=n_inc, setup=setup)

    def rhs(t, y):
        h = h0 - v * t
        rate = v / h
        return [rate, eta * law.sigma0(y[0], rate, y[1]) * rate / rho_c]

    times = dt * np.arange(n_inc + 1)
    ode = solve_ivp(rhs, (0.0, times[-1]), [0.0, T0], t_eval=times, rtol=1e-10, atol=1e-12)
    eps, T = 0.0, T0
    for n, ((h, F, vol), row) in enumerate(zip(out, sim.history)):
        rate = v / h
        s0 = law.sigma0(eps, rate, T)
        assert abs(F / (s0 * vol / h) - 1.0) < 1e-6, (n, F, s0 * vol / h)
        e_ode, T_ode = ode.y[:, n]
        assert abs(F / (law.sigma0(e_ode, rate, T_ode) * vol / h) - 1.0) < 5e-3
        eps += dt * rate
        T += dt * eta * s0 * rate / rho_c
        assert abs(row["heat_T_mean"] - T) < 1e-8 * T, (n, row["heat_T_mean"], T)
        assert abs(row["heat_T_max"] - row["heat_T_min"]) < 1e-8 * T   # homogeneous
        assert abs(T - ode.y[1, n + 1]) < 5e-3 * (ode.y[1, n + 1] - T0), (n, T, ode.y[1, n + 1])
        assert abs(row["heat_residual"]) < 1e-9 * row["heat_generated"]
        assert abs(row["heat_stored"] - row["heat_generated"]) < 1e-9 * row["heat_stored"]
    assert ode.y[1, -1] - T0 > 10.0            # the heating is large enough to soften the law


def _sliding_block(comm, b_tool, V=1.0, w=0.01, **kw):
    """A Norton–Hoff unit block on a static plane with Tresca friction (m̄ k = 1 MPa, far below
    the material's shear flow stress: the block slides as a rigid body), its top moved at
    (V, 0, −w) mm/s."""
    msh, _, ft = block(comm, (0, 0, 0), (1, 1, 1), 0.34)
    sp = fx.MixedSpace(msh)
    sim = fx.Simulation(sp, fx.NortonHoff(K=100.0, m=0.2, regularization=1e-4), progress=False,
                        name="slide", **kw)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["zmax"]), np.array([V, 0.0, -w]))
    law = Tresca(0.5, shear_limit=2.0)
    c = NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["zmin"]),
                     Plane((0, 0, 0), (0, 0, 1), name="anvil"), friction=law,
                     slip_velocity=1e-3)
    sim.add_contributor(c)
    thermal = fx.ThermalMaterial(rho_c=3.9, conductivity=30.0)
    heat = fx.WorkpieceHeat(sim, thermal, 20.0, tools={
        "anvil": fx.ToolHeat(temperature=20.0, h_c=0.0, effusivity=b_tool)})
    sim.add_controller(heat)
    return sim, law, thermal


def test_friction_heating_of_a_sliding_block():
    """A block sliding at V on a plane with Tresca friction receives β_f τ V S per second
    (β_f = b_w/(b_w + b_t), τ = m̄k, S the contact area) within 1 %, and exactly β_f times the
    contact's friction power; with h_c = 0 and no air nothing else enters the body."""
    V = 1.0
    thermal = fx.ThermalMaterial(rho_c=3.9, conductivity=30.0)
    b_tool = 3.0 * thermal.effusivity                      # β_f = 1/4
    sim, law, _ = _sliding_block(MPI.COMM_WORLD, b_tool, V=V)
    dt = 0.02
    sim.run(3 * dt, dt)
    beta = 0.25
    for r in sim.history[1:]:
        ref = beta * law.mbar * law.shear_limit * r["contact_area"] * V * dt
        assert abs(r["heat_friction"] - beta * r["contact_friction_power"] * dt) \
            < 1e-10 * ref
        assert abs(r["heat_friction"] / ref - 1.0) < 1e-2, (r["heat_friction"], ref)
        assert abs(r["heat_stored"] - r["heat_friction"] - r["heat_generated"]) \
            < 1e-8 * r["heat_stored"]
        assert r["heat_tools"] == 0.0 and r["heat_air"] == 0.0
    assert sim.history[-1]["heat_T_max"] > 20.0 + 1e-6


def test_heat_bad_input():
    """Heat on a small-strain material, a wrong thermal object, a bad tool entry."""
    msh, _, ft = block(MPI.COMM_WORLD, (0, 0, 0), (1, 1, 1), 0.5)
    thermal = fx.ThermalMaterial(rho_c=3.9, conductivity=30.0)
    small = fx.Simulation(fx.MixedSpace(msh), fx.LinearElastic(1000.0, 0.3), progress=False)
    with pytest.raises(ValueError, match="small-strain"):
        fx.WorkpieceHeat(small, thermal, 20.0)
    sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K=10.0, m=0.2), progress=False)
    with pytest.raises(ValueError, match="ThermalMaterial"):
        fx.WorkpieceHeat(sim, 3.9, 20.0)
    with pytest.raises(ValueError, match="ToolHeat"):
        fx.WorkpieceHeat(sim, thermal, 20.0, tools={"die": (20.0, 10.0)})
    with pytest.raises(ValueError, match="absolute zero"):
        fx.ToolHeat(temperature=-300.0, h_c=10.0)
    with pytest.raises(ValueError, match="h_c"):
        fx.ToolHeat(temperature=20.0, h_c=float("nan"))
    assert dataclasses.is_dataclass(fx.ToolHeat(20.0, 10.0))
    for probes, what in (({"a/b": (0, 0, 0)}, "label"), ({"core": (0, 0)}, "3 coordinates"),
                         ({"core": (0, 0, float("nan"))}, "finite point"),
                         ([(0, 0, 0)], "dict")):
        with pytest.raises(ValueError, match=what):
            fx.WorkpieceHeat(sim, thermal, 20.0, probes=probes)


def test_heat_checkpoint_resumes_the_temperature():
    """A run with friction heating checkpointed at increment 2 and resumed gives the
    uninterrupted run's temperatures and heat balances (to 1e-10)."""
    thermal = fx.ThermalMaterial(rho_c=3.9, conductivity=30.0)
    d = shared_tmpdir("fxc_heat_ckpt_")
    sims = []
    for k in range(2):
        sim, _, _ = _sliding_block(MPI.COMM_WORLD, thermal.effusivity, output_dir=d,
                                   checkpoint_every=2 if k == 0 else 0, overwrite=True)
        sims.append(sim)
    sims[0].run(0.08, 0.02)
    ck = list_checkpoints(os.path.join(d, "checkpoints"), "slide")
    sims[1].resume(ck[0])
    sims[1].run(0.08, 0.02)
    a, b = sims[0].history, sims[1].history
    assert len(a) == len(b) == 4
    for k in ("heat_T_max", "heat_T_mean", "heat_stored", "heat_friction"):
        assert abs(a[-1][k] - b[-1][k]) <= 1e-10 * abs(a[-1][k]), (k, a[-1][k], b[-1][k])
    assert a[-1]["heat_T_max"] > a[1]["heat_T_max"] > 20.0
    if MPI.COMM_WORLD.rank == 0:
        shutil.rmtree(d, ignore_errors=True)


def test_heat_follows_a_remesh():
    """A quarter billet compressed (sliding plates) and cooled by air on its side: after a
    remesh the temperature is interpolated on the new mesh (extremes and mean kept to the
    interpolation error, the field on the new mesh) and the run goes on with the heat coupled."""
    msh, _, ft = cylinder_billet(MPI.COMM_WORLD, 1.0, 1.0, 0.3)
    sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K=100.0, m=0.2, regularization=1e-4),
                        progress=False)
    f = {k: sim.facets(ft, v) for k, v in BILLET_TAGS.items()}
    sim.add_velocity_bc(f["top"], -0.1, 2)
    sim.add_velocity_bc(f["bottom"], 0.0, 2)
    sim.add_velocity_bc(f["symmetry_x"], 0.0, 0)
    sim.add_velocity_bc(f["symmetry_y"], 0.0, 1)
    air = {BILLET_TAGS["lateral"]: fx.AirExchange(h=1.0, temperature=20.0)}
    # probes (thermocouples): on the axis, the hottest; at the side's mid-height, the coldest
    heat = fx.WorkpieceHeat(sim, fx.ThermalMaterial(rho_c=3.9, conductivity=3.0), 600.0,
                            air=air, facet_tags=ft, probes={"axis": (0.0, 0.0, 0.5),
                                                            "side": (1.0, 0.0, 0.5)})
    sim.add_controller(heat)
    sim.run(0.4, 0.2)
    before = {k: sim.history[-1][f"heat_T_{k}"] for k in ("min", "mean", "max")}
    spread = before["max"] - before["min"]
    assert spread > 1.0
    probe = {k: sim.history[-1][f"heat_T_at_{k}"] for k in ("axis", "side")}
    # each probe reads T at the vertex nearest where its point went (an independent search)
    X = np.concatenate(MPI.COMM_WORLD.allgather(heat.problem.dof_coordinates()))
    T = np.concatenate(MPI.COMM_WORLD.allgather(heat.temperature.x.array))
    for k, (x0, z0) in (("axis", (0.0, 0.5)), ("side", (1.0, 0.5))):
        near = np.argmin(np.hypot(np.hypot(X[:, 0] - x0, X[:, 1]), X[:, 2] - z0))
        assert abs(probe[k] - T[near]) < 0.05 * spread, (k, probe[k], T[near])
    assert probe["axis"] > before["mean"] > probe["side"]
    sim.remesh(size=0.25)
    p = heat.problem
    assert heat.temperature.function_space.mesh is sim.mesh
    for k, now in (("min", p.min_temperature()), ("mean", p.mean_temperature()),
                   ("max", p.max_temperature())):
        assert abs(now - before[k]) < 0.05 * spread, (k, now, before[k])
    # the probes found again on the new mesh: the same temperatures, to the interpolation
    after = heat.diagnostics()
    for k in ("axis", "side"):
        assert abs(after[f"heat_T_at_{k}"] - probe[k]) < 0.05 * spread, (k, after, probe)
    sim.run(0.6, 0.2)
    r = sim.history[-1]
    assert r["heat_air"] < 0 and abs(r["heat_residual"]) < 1e-8 * abs(r["heat_stored"])
    assert r["heat_T_at_axis"] > r["heat_T_mean"] > r["heat_T_at_side"]


def test_heat_added_twice_or_different_on_the_ranks_refused():
    """A second WorkpieceHeat on one simulation is refused (made after the first was added, or
    both added: before any heat is counted twice); a thermal set-up that differs between the
    ranks raises on every rank instead of computing another heat on one of them."""
    msh, _, ft = block(MPI.COMM_WORLD, (0, 0, 0), (1, 1, 1), 0.5)
    thermal = fx.ThermalMaterial(rho_c=3.9, conductivity=30.0)
    sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K=10.0, m=0.2), progress=False)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["zmax"]), np.array([0.0, 0.0, -0.1]))
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["zmin"]), np.array([0.0, 0.0, 0.0]))
    first = fx.WorkpieceHeat(sim, thermal, 20.0)
    second = fx.WorkpieceHeat(sim, thermal, 20.0)
    sim.add_controller(first)
    with pytest.raises(ValueError, match="already has a WorkpieceHeat"):
        fx.WorkpieceHeat(sim, thermal, 20.0)
    sim.add_controller(second)
    with pytest.raises(ValueError, match="several WorkpieceHeat"):
        sim.step(0.1)
    if MPI.COMM_WORLD.size > 1:
        sim2 = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K=10.0, m=0.2), progress=False)
        k = 30.0 + MPI.COMM_WORLD.rank
        with pytest.raises(ValueError, match="thermal"):
            fx.WorkpieceHeat(sim2, fx.ThermalMaterial(rho_c=3.9, conductivity=k), 20.0)


def test_tresca_limit_reads_the_local_flow_stress():
    """The Tresca limit m̄k of a contact on a flow-stress material takes k of each node's own
    cells — their temperature here — not the law's reference at ε̄ = 0 and the material's
    nominal temperature: a block at 1050 °C (by its heat, the material saying 950 °C) with a
    table that is one power law per temperature slides and is pressed exactly as the plain
    Norton–Hoff law of that power law at 1050 °C (friction force to 1e-7; the penalty given
    as ρ, not scaled by the law's reference K); the reference at 950 °C would make k 1.3 times
    larger. The heat takes nothing (η_q = 0, the tool's
    effusivity takes all the friction heat)."""
    strains, rates, temps = np.array([0.0]), np.array([0.1, 10.0]), np.array([950.0, 1150.0])
    stress = np.array([[[130.0, 70.0], [260.0, 140.0]]])   # m = ln 2 / ln 100 at each T
    flow = fx.TabulatedFlowStress(strains, rates, temps, stress)
    hot = fx.Viscoplastic(flow, regularization=1e-4, temperature=1050.0).reference()
    cold = fx.Viscoplastic(flow, regularization=1e-4, temperature=950.0).reference()
    assert cold.K / hot.K == pytest.approx(1.3, rel=1e-12)
    forces = {}
    for name, mat in (("table", fx.Viscoplastic(flow, regularization=1e-4, temperature=950.0)),
                      ("plain", fx.NortonHoff(K=hot.K, m=hot.m, regularization=1e-4))):
        msh, _, ft = block(MPI.COMM_WORLD, (0, 0, 0), (1, 1, 1), 0.34)
        sp = fx.MixedSpace(msh)
        sim = fx.Simulation(sp, mat, progress=False)
        sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["zmax"]), np.array([1.0, 0.0, -0.05]))
        c = NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["zmin"]),
                         Plane((0, 0, 0), (0, 0, 1), name="anvil"), friction=Tresca(0.5),
                         slip_velocity=1e-3, penalty=Penalty(penalty=1e4))   # ρ as given
        sim.add_contributor(c)
        sim.add_controller(fx.WorkpieceHeat(
            sim, fx.ThermalMaterial(rho_c=3.9, conductivity=30.0, taylor_quinney=0.0), 1050.0,
            tools={"anvil": fx.ToolHeat(temperature=1050.0, h_c=0.0, effusivity=1e12)}))
        sim.run(0.04, 0.02)
        forces[name] = np.array([r["anvil_friction_x"] for r in sim.history])
    assert np.all(np.abs(forces["table"]) > 0.1)
    np.testing.assert_allclose(forces["table"], forces["plain"], rtol=1e-7)
