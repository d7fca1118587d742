"""Friction demos at reduced size (serial and on 2 ranks): upsetting between Plane dies with
Tresca / Coulomb friction against the upper bound and the slab estimate
(:mod:`fxcontact.processes.upsetting_dies`, told in ``demos/demo_upsetting.py``), and the ring
test against Avitzur's upper bound (:mod:`fxcontact.processes.ring_test`, told in
``demos/demo_ring_test.py``) (THEORY §14.5).

What theory guarantees is asserted: the FE mean die pressure stays below the Tresca upper bound
(the FE field minimises the power over a space that contains the bound's homogeneous field);
frictionless dies reproduce the sliding (velocity BC) solution; Tresca m̄ = 1 dies, which may
slip at the cost of the shear flow stress, need no more power than the no-slip (sticking BC)
dies; a ring's hole grows without friction and shrinks with sticking friction, monotonically in
m̄. The rest is measured and printed (``pytest -s``). Measured (serial):

upsetting, R 10, H 10 (d/h = 2), h = 5, 10 % reduction (start-up + 2 increments), last
increment, p̄/σ₀ FE / upper bound: m̄ = 0: 0.9999 / 1; 0.1: 1.0399 / 1.0416 (−0.2 %);
0.3: 1.1113 / 1.1247 (−1.2 %); 1: 1.2849 / 1.4156 (−9.2 %: not within 5 %: barrelling, and a
coarse mesh); sticking BC 1.4005 (m̄ = 1 is 8.3 % lower); Coulomb μ = 0.2: 1.1227 against the
slab's 1.1609.

ring 60:30:20, h = 5, 20 % reduction (start-up + 2 increments), change of the minimum inner
diameter FE / upper bound [%]: m̄ = 0: 10.86 / 11.80 (explicit geometry update, 10 % steps);
0.3: −0.00 / −1.73; 1: −9.70 / −9.14 (mid-height −9.00, die face −2.50: the bore barrels); die
force F/(σ₀A₀) FE / UB: 1.108 / 1.117, 1.292 / 1.312, 1.445 / 1.580.
"""

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.processes import ring_test, upsetting_dies
from helpers import assert_histories_match, assert_newton_counts_match

#: short billet (d/h = 2), coarse mesh, 10 % reduction in 2 increments (+ start-up)
# the volume correction (on by default) adds a volumetric rate of the order of one increment's
# volume error (0.25 % per increment here), which does work through the pressure and shifts p̄
# by as much: the comparisons with the bounds are made on the plain incompressible update
UPSET = dict(volume_correction="none", radius=10.0, height=10.0, h=5.0, reduction=0.1,
             n_steps=2, output_dir=None,
             picture=False, progress=False)


def _say(*args):
    if MPI.COMM_WORLD.rank == 0:
        print(*args)


@pytest.fixture(scope="module")
def upsetting():
    runs = {"sliding": upsetting_dies.run(dies="sliding", **UPSET),
            "sticking": upsetting_dies.run(dies="sticking", **UPSET),
            "coulomb": upsetting_dies.run(dies="coulomb", mu=0.2, **UPSET)}
    for mb in (0.0, 0.1, 0.3, 1.0):
        runs[mb] = upsetting_dies.run(dies="tresca", mbar=mb, **UPSET)
    _say("\nupsetting d/h = 2, 10 %: p/sigma0 (homogeneous face; actual face) vs bounds")
    for k, r in runs.items():
        _say(f"  {k!s:>8}: p {r['p_mean'][-1]:.4f}; {r['p_face'][-1]:.4f}  UB "
             f"{r['upper_bound'][-1]:.4f}  slab {r['slab'][-1]:.4f}  r_mid {r['radius_mid']:.3f}"
             f"  r_end {r['radius_end']:.3f}")
    return runs


@pytest.mark.parametrize("mbar", [0.1, 0.3, 1.0])
def test_upsetting_tresca_below_upper_bound(upsetting, mbar):
    """p̄/σ₀ below 1 + m̄d/(3√3h) at the last increment, and above the frictionless 1."""
    r = upsetting[mbar]
    p, ub = r["p_mean"][-1], r["upper_bound"][-1]
    assert 1.0 < p < ub
    _say(f"m = {mbar}: FE {p:.4f}, UB {ub:.4f}, FE/UB - 1 = {p / ub - 1:+.2%}")


@pytest.mark.parametrize("mbar", [0.1, 0.3, pytest.param(1.0, marks=pytest.mark.xfail(
    strict=True, reason="measured FE/UB - 1 = -9.2 % at m = 1 (d/h = 2, 10 %; -15.7 % for the "
    "demo's d/h = 4/3 at 30 %): the homogeneous-field bound ignores the barrelling that strong "
    "friction causes (the FE solution is below the bound, as the bound theorem requires, but "
    "not within 5 %)"))])
def test_upsetting_tresca_within_5_percent_of_bound(upsetting, mbar):
    """Short billet (d/h = 2): the FE mean pressure within 5 % of the upper bound."""
    r = upsetting[mbar]
    p, ub = r["p_mean"][-1], r["upper_bound"][-1]
    assert abs(p / ub - 1.0) < 0.05


def test_upsetting_pressure_increases_with_friction(upsetting):
    p = [upsetting[mb]["p_mean"][-1] for mb in (0.0, 0.1, 0.3, 1.0)]
    assert np.all(np.diff(p) > 0)
    # more friction, more barrelling: bulge r_mid − r_end grows
    bulge = [upsetting[mb]["radius_mid"] - upsetting[mb]["radius_end"] for mb in (0.1, 0.3, 1.0)]
    assert np.all(np.diff(bulge) > 0)


def test_upsetting_frictionless_dies_match_sliding_bc(upsetting):
    """m̄ = 0 Plane dies (penalty contact) against the sliding velocity BC: the homogeneous
    field, p̄/σ₀ = 1 (the penalty's penetration rate is ~1e-3 of the die speed)."""
    a, b = upsetting[0.0], upsetting["sliding"]
    assert abs(b["p_mean"][-1] - 1.0) < 1e-5     # measured 2e-6
    assert abs(a["p_mean"][-1] - 1.0) < 1e-3     # measured 1e-4
    assert abs(a["radius_mid"] - b["radius_mid"]) < 1e-3 * 10.0
    assert abs(a["radius_mid"] - a["radius_end"]) < 1e-3 * 10.0


def test_upsetting_full_tresca_below_sticking(upsetting):
    """m̄ = 1 (slip allowed at the cost of k) needs at most the power of no-slip dies."""
    a, b = upsetting[1.0], upsetting["sticking"]
    assert a["p_mean"][-1] < b["p_mean"][-1]
    _say(f"m = 1: {a['p_mean'][-1]:.4f} vs sticking BC {b['p_mean'][-1]:.4f} "
         f"({a['p_mean'][-1] / b['p_mean'][-1] - 1:+.2%})")


def test_upsetting_coulomb(upsetting):
    """Coulomb μ = 0.2 raises the pressure above the frictionless value; the slab estimate
    (which ignores the Tresca limit and barrelling) is printed next to it."""
    r = upsetting["coulomb"]
    assert r["p_mean"][-1] > 1.0 + 1e-3
    _say(f"Coulomb mu = 0.2: FE {r['p_mean'][-1]:.4f}, slab {r['slab'][-1]:.4f}")


def test_upsetting_bad_dies():
    with pytest.raises(ValueError, match="dies"):
        upsetting_dies.run(dies="glued", output_dir=None)
    with pytest.raises(ValueError, match="mbar"):
        upsetting_dies.run(dies="tresca", mbar=1.5, **UPSET)


RING = dict(h=5.0, reduction=0.2, n_steps=2, output_dir=None, picture=False, progress=False)


@pytest.fixture(scope="module")
def ring():
    res = ring_test.run(mbars=(0.0, 0.3, 1.0), **RING)
    _say("\nring 60:30:20, % change of the minimum ID, FE vs upper bound")
    for mb, r in res["fe"].items():
        _say(f"  m = {mb}: reduction {100 * r['reduction'][-1]:.1f} %: FE {r['id_min'][-1]:.2f} "
             f"(mid {r['id_mid'][-1]:.2f}, face {r['id_face'][-1]:.2f}), UB "
             f"{res['ub'][mb]['id_change'][-1]:.2f}; force FE {r['force'][-1]:.3f}, UB "
             f"{res['ub'][mb]['force'][-1]:.3f}")
    return res


def _at(r, key, eps):
    """FE curve ``key`` at the height reductions ``eps`` (cut-backs add points)."""
    return np.interp(eps, r["reduction"], r[key])


@pytest.mark.slow
def test_ring_hole_grows_without_friction_and_shrinks_with_it(ring):
    fe = ring["fe"]
    assert fe[0.0]["id_min"][-1] > 0.0
    assert fe[1.0]["id_min"][-1] < 0.0
    # the curves are ordered by friction at the nominal increments' ends
    eps = RING["reduction"] * np.arange(1, RING["n_steps"] + 1) / RING["n_steps"]
    for lo, hi in ((0.0, 0.3), (0.3, 1.0)):
        for key in ("id_min", "id_mid"):
            assert np.all(_at(fe[lo], key, eps) > _at(fe[hi], key, eps))


@pytest.mark.slow
def test_ring_side_by_side_with_upper_bound(ring):
    """The FE and upper-bound curves are produced at the same reductions. Without friction the
    FE ring stays straight (mid-height = die face) and follows the homogeneous bound up to the
    explicit geometry update's error (r ← r(1 + a/2) per increment of height strain a, against
    (1 − a)^(−1/2)), which the volume correction reduces: between the two."""
    for mb, r in ring["fe"].items():
        u = ring["ub"][mb]
        assert len(u["id_change"]) == len(r["id_min"])
        assert np.allclose(ring["diff"][mb]["id_min"], r["id_min"] - u["id_change"])
    r, u = ring["fe"][0.0], ring["ub"][0.0]
    # straight bore up to the penalty's penetration (measured 1e-3 percentage points)
    assert np.allclose(r["id_mid"], r["id_face"], atol=1e-2)
    T = 1.0 - r["reduction"]
    euler = 100 * (np.cumprod(np.r_[1.0, 1.0 + 0.5 * (T[:-1] - T[1:]) / T[:-1]]) - 1.0)
    # the volume correction gives back what the explicit update loses: above the Euler
    # curve, below the exact homogeneous one
    assert np.all(r["id_min"][1:] > euler[1:] - 0.05)
    assert np.all(r["id_min"][1:] < u["id_change"][1:])
    _say(f"ring m = 0: FE {r['id_min'][1:]}, Euler update {euler[1:]}, exact {u['id_change'][1:]}")
    # force: the homogeneous bound is exact without friction (σ₀ at v/T)
    assert np.allclose(r["force"][2:], u["force"][2:], rtol=1e-2)


def test_friction_run_parallel_matches_serial(upsetting):
    """Upsetting with Tresca dies (m̄ = 0.3) on all ranks against a COMM_SELF run (1e-8)."""
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        pytest.skip("needs several ranks (the serial run is the reference)")
    par = upsetting[0.3]
    ser = upsetting_dies.run(dies="tresca", mbar=0.3, **UPSET, comm=MPI.COMM_SELF)
    keys = ("die_force_z", "die_friction_x", "die_friction_y", "base_force_z",
            "contact_friction_power")
    assert_histories_match(par["history"], ser["history"], keys, 1e-8, scale_key="die_force_z")
    for a, b in zip(par["history"], ser["history"]):
        assert a["contact_nodes"] == b["contact_nodes"]
        assert_newton_counts_match(a["newton_iterations"], b["newton_iterations"])
    assert abs(par["p_mean"][-1] - ser["p_mean"][-1]) < 1e-8
