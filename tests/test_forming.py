"""Forming theory (pure numpy/scipy): upsetting bounds and Avitzur's ring-compression upper
bound (THEORY §14.5), checked against the stated values, limits and independent quadratures."""

import math

import numpy as np
import pytest
from scipy import integrate

from fxcontact.theory.forming import (flow_stress, ring_compression_upper_bound, ring_neutral_radius,
                               ring_power, ring_power_quadrature, upsetting_slab_coulomb,
                               upsetting_upper_bound)

MBARS = (0.0, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0)
EPS = np.linspace(0.0, 0.5, 11)


def test_flow_stress():
    # σ₀ = √3 K (√3 ε̇)^m; m = 1 is a Newtonian fluid of viscosity K: σ₀ = 3 K ε̇
    assert flow_stress(2.0, 1.0, 0.5) == pytest.approx(3.0)
    assert flow_stress(50.0, 0.15, 1.0 / math.sqrt(3.0)) == pytest.approx(50.0 * math.sqrt(3.0))
    with pytest.raises(ValueError, match="m"):
        flow_stress(1.0, 0.0, 1.0)


def test_upsetting_upper_bound_equals_tresca_slab():
    """Homogeneous field with τ = m̄k: the same as the slab p(r) = σ₀ + 2m̄k(R − r)/h,
    averaged over the end face by quadrature."""
    for mbar, d, h in ((0.3, 20.0, 15.0), (1.0, 40.0, 10.0), (0.0, 5.0, 5.0)):
        R, k = 0.5 * d, 1.0 / math.sqrt(3.0)
        mean = 2.0 / R ** 2 * integrate.quad(lambda r: (1 + 2 * mbar * k * (R - r) / h) * r,
                                             0, R)[0]
        assert upsetting_upper_bound(mbar, d, h) == pytest.approx(mean, rel=1e-12)
    with pytest.raises(ValueError, match="mbar"):
        upsetting_upper_bound(1.5, 1.0, 1.0)


def test_coulomb_slab_quadrature_and_small_friction():
    """p(r) = σ₀ exp(2μ(R − r)/h) (dp/dr = −2μp/h, p(R) = σ₀) averaged by quadrature; for small
    x = 2μR/h the series 1 + μd/(3h) (continuous across the series switch)."""
    for mu, R, h in ((0.1, 10.0, 15.0), (0.3, 20.0, 10.0), (0.5, 30.0, 5.0)):
        mean = 2.0 / R ** 2 * integrate.quad(lambda r: math.exp(2 * mu * (R - r) / h) * r, 0,
                                             R, epsrel=1e-13)[0]
        assert upsetting_slab_coulomb(mu, R, h) == pytest.approx(mean, rel=1e-10)
    assert upsetting_slab_coulomb(0.0, 10.0, 5.0) == 1.0
    for x in (0.99e-4, 1.01e-4):  # either side of the series switch
        mu = x * 5.0 / 20.0
        assert upsetting_slab_coulomb(mu, 10.0, 5.0) == pytest.approx(
            1.0 + mu * 20.0 / 15.0, rel=1e-8)


def test_ring_power_closed_form_matches_quadrature():
    """The closed-form J (primitive of √(3u² + b²)/u) against adaptive quadrature of the
    integrals as written, with R_n below, inside and above the ring."""
    for Rn, Ri, Ro, T, mbar in ((0.0, 15.0, 30.0, 20.0, 0.3), (10.0, 15.0, 30.0, 20.0, 0.3),
                                (18.7, 15.0, 30.0, 20.0, 1.0), (30.0, 15.0, 30.0, 20.0, 0.5),
                                (4.0, 1.0, 9.0, 2.0, 0.1)):
        assert ring_power(Rn, Ri, Ro, T, mbar) == pytest.approx(
            ring_power_quadrature(Rn, Ri, Ro, T, mbar), rel=1e-10)


def test_solid_disc_gives_upsetting_bound():
    for mbar in (0.0, 0.4, 1.0):
        R, T = 10.0, 7.0
        assert ring_neutral_radius(0.0, R, T, mbar) == 0.0
        p = ring_power(0.0, 0.0, R, T, mbar) / (math.pi * R ** 2)
        assert p == pytest.approx(upsetting_upper_bound(mbar, 2 * R, T), rel=1e-13)
    assert ring_power(1.0, 0.0, 10.0, 7.0, 0.5) == math.inf


def test_frictionless_ring_flows_outwards():
    """m̄ = 0: J increases with R_n (sampled), the minimiser is R_n = 0 exactly, and the 6:3:2
    ring's hole grows by 19.5 % of D_i at 30 % height reduction, 41.4 % at 50 % (THEORY §14.5;
    homogeneous: R_i ∝ (1 − ε)^(−1/2))."""
    Rn = np.linspace(0.0, 30.0, 61)
    J = np.array([ring_power(r, 15.0, 30.0, 20.0, 0.0) for r in Rn])
    assert np.all(np.diff(J) > 0)
    assert ring_neutral_radius(15.0, 30.0, 20.0, 0.0) == 0.0
    r = ring_compression_upper_bound(30.0, 15.0, 20.0, 0.0, [0.3, 0.5])
    assert np.round(r["id_change"], 1).tolist() == [19.5, 41.4]
    assert np.allclose(r["id_change"], 100 * ((1 - r["reduction"]) ** -0.5 - 1), rtol=1e-8)
    assert np.allclose(r["pressure"], 1.0, rtol=1e-12)


@pytest.mark.parametrize("geometry", [(15.0, 30.0, 20.0), (15.0, 30.0, 10.0), (3.0, 30.0, 8.0)])
def test_neutral_radius_is_the_minimiser(geometry):
    """minimize_scalar's answer against a brute-force grid of 30001 radii over [0, R_o]."""
    Ri, Ro, T = geometry
    grid = np.linspace(0.0, Ro, 30001)
    for mbar in (0.05, 0.2, 0.5, 1.0):
        Rn = ring_neutral_radius(Ri, Ro, T, mbar)
        J = np.array([ring_power(r, Ri, Ro, T, mbar) for r in grid])
        assert ring_power(Rn, Ri, Ro, T, mbar) <= J.min() * (1 + 1e-12)
        assert abs(Rn - grid[np.argmin(J)]) <= 2 * (grid[1] - grid[0])
        assert Rn > 0.0  # friction: some material flows inwards


def test_ring_curves_monotone_in_friction_and_conserve_volume():
    curves = [ring_compression_upper_bound(30.0, 15.0, 20.0, m, EPS) for m in MBARS]
    idc = np.array([c["id_change"] for c in curves])
    p = np.array([c["pressure"] for c in curves])
    # more friction: smaller hole, higher pressure at every reduction > 0
    assert np.all(np.diff(idc[:, 1:], axis=0) < 0)
    assert np.all(np.diff(p, axis=0) > 0)
    # low friction: the hole grows; sticking: it shrinks
    assert np.all(idc[1, 1:] > 0) and np.all(idc[-1, 1:] < 0)
    for c in curves:
        V = (c["outer_radius"] ** 2 - c["inner_radius"] ** 2) * c["height"]
        assert np.allclose(V, V[0], rtol=1e-8)
        # the outer diameter always grows (R_n < R_o)
        assert np.all(np.diff(c["outer_radius"]) > 0)


def test_ring_bad_input():
    with pytest.raises(ValueError, match="inner_radius"):
        ring_compression_upper_bound(10.0, 12.0, 5.0, 0.2, [0.1])
    with pytest.raises(ValueError, match="inner_radius"):
        ring_compression_upper_bound(10.0, 0.0, 5.0, 0.2, [0.1])
    with pytest.raises(ValueError, match="reductions"):
        ring_compression_upper_bound(10.0, 5.0, 5.0, 0.2, [0.3, 0.1])
    with pytest.raises(ValueError, match="mbar"):
        ring_compression_upper_bound(10.0, 5.0, 5.0, -0.1, [0.1])


def test_ring_power_slope_by_finite_differences():
    """The analytic slope dJ/d(R_n²) used to polish the minimiser, against central differences
    of the closed-form J (R_n below and inside the ring, several friction factors)."""
    from fxcontact.theory.forming import ring_power_slope

    Ri, Ro, T = 15.0, 30.0, 20.0
    for mbar in (0.0, 0.4, 1.0):
        for Rn in (5.0, 14.0, 17.0, 29.0):
            b, db = Rn * Rn, 1e-4 * Rn * Rn
            fd = (ring_power(math.sqrt(b + db), Ri, Ro, T, mbar)
                  - ring_power(math.sqrt(b - db), Ri, Ro, T, mbar)) / (2 * db)
            assert ring_power_slope(Rn, Ri, Ro, T, mbar) == pytest.approx(fd, rel=1e-6, abs=1e-9)


# ------------------------------------------------------------------------------ ring rolling
def test_ring_rolling_worked_example():
    """THEORY §14.4 example: R1 = 150, R2 = 40, R = 100, r = 60, H = 40 mm, μ = 0.3,
    σ₀ = 100 MPa: window 0.26–4.24 mm/rev, L = 8.94 mm at 1 mm/rev, F ≈ 70 kN."""
    from fxcontact.theory.forming import (ring_rolling_contact_length, ring_rolling_feed_window,
                                   ring_rolling_force)
    w = ring_rolling_feed_window(150.0, 40.0, 100.0, 60.0, mu=0.3)
    assert w["min"] == pytest.approx(0.26, abs=0.005)
    assert w["max"] == pytest.approx(4.24, abs=0.005)
    L = ring_rolling_contact_length(1.0, 150.0, 40.0, 100.0, 60.0)
    assert L == pytest.approx(8.94, abs=0.005)
    F = ring_rolling_force(100.0 / math.sqrt(3.0), 40.0, L, 40.0)
    assert F["force"] == pytest.approx(70e3, rel=0.01)


def test_ring_rolling_geometry_checks():
    """L is the chord of the two arcs (outer on the main roll, inner on the mandrel) meeting
    with the wall reduced by Δh: L² (1/(2R1) + 1/(2R) + 1/(2R2) − 1/(2r)) = Δh to first order;
    the feed speed makes Δh per ring revolution; D_m from the volume of a rectangular ring."""
    from fxcontact.theory.forming import (ring_rolling_contact_length, ring_rolling_feed_speed,
                                   ring_rolling_mean_diameter, ring_rolling_force)
    R1, R2, R, r = 300.0, 60.0, 250.0, 180.0
    for dh in (0.1, 1.0, 3.0):
        L = ring_rolling_contact_length(dh, R1, R2, R, r)
        # sagitta of each surface at the distance L from the bite line
        sag = sum(s * (Ri - math.sqrt(Ri * Ri - L * L)) for s, Ri in
                  ((1, R1), (1, R2), (1, R), (-1, r)))
        assert sag == pytest.approx(dh, rel=0.03)   # first order in L/R (L/R2 = 0.3 at 3 mm)
    w1 = 2 * math.pi * 0.5
    vf = ring_rolling_feed_speed(2.0, w1, R1, R)
    # time of one ring revolution 2πR/(ω1R1), times v_f = Δh
    assert vf * 2 * math.pi * R / (w1 * R1) == pytest.approx(2.0)
    V = math.pi * (R**2 - r**2) * 40.0
    assert ring_rolling_mean_diameter(V, 40.0, R - r) == pytest.approx(R + r)
    with pytest.raises(ValueError, match="8.74"):
        ring_rolling_force(50.0, 40.0, 1.0, 10.0)
    with pytest.raises(ValueError, match="mandrel"):
        ring_rolling_contact_length(1.0, R1, 200.0, R, r)
# ------------------------------------------------------------------------------ drawing
def test_drawing_worked_example():
    """THEORY §14.2's worked example: σ₀ = 300 MPa, D 10 → 8.944 mm (20 % area), α = 8°:
    ideal 66.9, Avitzur m̄ = 0: 99.3, m̄ = 0.1: 126.8 MPa (values quoted to 0.1 MPa)."""
    from fxcontact.theory.forming import drawing_ideal_stress, drawing_upper_bound
    a = math.radians(8.0)
    assert drawing_ideal_stress(300.0, 5.0, 4.472) == pytest.approx(66.9, abs=0.1)
    assert drawing_upper_bound(300.0, 5.0, 4.472, a) == pytest.approx(99.3, abs=0.1)
    assert drawing_upper_bound(300.0, 5.0, 4.472, a, mbar=0.1) == pytest.approx(126.8, abs=0.1)


def test_avitzur_f_limits_and_bound_limits():
    """f(α) → 1 as α → 0 (series branch continuous with the closed form), f > 1 and increasing;
    the frictionless bound tends to the ideal work as α → 0 (redundant work ~ α), and stays
    above it; the land adds 2m̄/√3 L/R_f σ₀."""
    from fxcontact.theory.forming import avitzur_f, drawing_ideal_stress, drawing_upper_bound
    assert avitzur_f(0.0) == 1.0
    lo, hi = avitzur_f(1e-2 * (1 - 1e-9)), avitzur_f(1e-2 * (1 + 1e-9))
    assert abs(lo - hi) < 1e-11 and abs(lo - 1.0) < 1e-5
    al = np.radians(np.linspace(0.5, 60.0, 50))
    f = avitzur_f(al)
    assert np.all(f > 1.0) and np.all(np.diff(f) > 0)
    ideal = drawing_ideal_stress(1.0, 10.0, 7.5)
    for a in np.radians([0.01, 0.1]):
        ub = drawing_upper_bound(1.0, 10.0, 7.5, a)
        assert ideal < ub < ideal * (1 + 2 * a)
    ub = drawing_upper_bound(1.0, 10.0, 7.5, 0.2, mbar=0.3)
    ub_land = drawing_upper_bound(1.0, 10.0, 7.5, 0.2, mbar=0.3, land_length=2.0)
    assert ub_land - ub == pytest.approx(2 * 0.3 / math.sqrt(3.0) * 2.0 / 7.5, rel=1e-12)
    with pytest.raises(ValueError, match="semi-angle"):
        drawing_upper_bound(1.0, 10.0, 7.5, 2.0)
    with pytest.raises(ValueError, match="smaller"):
        drawing_ideal_stress(1.0, 7.5, 10.0)


def test_sachs_against_slab_ode():
    """Sachs' closed form equals the slab equation dσ/dD = 2(Bσ − (1 + B)σ₀)/D integrated
    numerically from D₀ (σ = 0) down to D_f; μ = 0 gives the ideal work."""
    from fxcontact.theory.forming import drawing_ideal_stress, drawing_sachs_stress
    R0, Rf, s0 = 10.0, 7.5, 250.0
    for mu, a in ((0.05, 0.15), (0.1, 0.2), (0.2, 0.1)):
        B = mu / math.tan(a)
        sol = integrate.solve_ivp(lambda D, s: [2.0 * (B * s[0] - (1 + B) * s0) / D],
                                  (2 * R0, 2 * Rf), [0.0], rtol=1e-12, atol=1e-10)
        assert drawing_sachs_stress(s0, R0, Rf, a, mu) == pytest.approx(sol.y[0, -1], rel=1e-8)
    assert drawing_sachs_stress(s0, R0, Rf, 0.2, 0.0) == pytest.approx(
        drawing_ideal_stress(s0, R0, Rf), rel=1e-14)
    assert drawing_sachs_stress(s0, R0, Rf, 0.2, 1e-9) == pytest.approx(
        drawing_ideal_stress(s0, R0, Rf), rel=1e-8)


def test_drawing_mean_strain_rate_is_ln_over_transit_time():
    """The mean rate is ln(A₀/A_f) over the transit time through the cone of the homogeneous
    field v(z) = v₀ (R₀/R(z))² (transit time by quadrature)."""
    from fxcontact.theory.forming import drawing_mean_strain_rate
    R0, Rf, v0 = 10.0, 7.5, 56.25
    for a in np.radians([5.0, 10.0, 20.0]):
        t, _ = integrate.quad(lambda z: (R0 - z * math.tan(a)) ** 2 / (v0 * R0 ** 2), 0.0,
                              (R0 - Rf) / math.tan(a), epsabs=0, epsrel=1e-13)
        assert drawing_mean_strain_rate(R0, Rf, a, v0) == pytest.approx(
            2 * math.log(R0 / Rf) / t, rel=1e-10)


def test_drawing_optimal_angle_and_theory_band():
    """The optimum minimises the bound (neighbouring angles give more) and is close to the
    classical √(1.5 m̄ ln(R₀/R_f)); no optimum without friction; the band of a Norton–Hoff
    material uses σ₀ = √3 K (√3 ε̇)^m at the mean rate."""
    from fxcontact.theory.forming import (drawing_mean_strain_rate, drawing_optimal_angle,
                                   drawing_theory, drawing_upper_bound)
    for mbar in (0.05, 0.1, 0.3):
        a = drawing_optimal_angle(10.0, 7.5, mbar)
        ub = drawing_upper_bound(1.0, 10.0, 7.5, a, mbar)
        assert ub < drawing_upper_bound(1.0, 10.0, 7.5, a * 1.02, mbar)
        assert ub < drawing_upper_bound(1.0, 10.0, 7.5, a * 0.98, mbar)
        assert drawing_optimal_angle(10.0, 7.5, mbar, approximate=True) == pytest.approx(
            a, rel=0.05)
    with pytest.raises(ValueError, match="no optimal"):
        drawing_optimal_angle(10.0, 7.5, 0.0)
    th = drawing_theory(445.0, 0.016, 10.0, 7.5, math.radians(10.0), 100.0)
    rate = drawing_mean_strain_rate(10.0, 7.5, math.radians(10.0), 100.0 * 0.75 ** 2)
    assert th["strain_rate"] == pytest.approx(rate, rel=1e-14)
    assert th["sigma0"] == pytest.approx(flow_stress(445.0, 0.016, rate), rel=1e-14)
    assert th["ideal"] < th["avitzur"] and th["sachs"] == pytest.approx(th["ideal"])


def test_extrusion_theory():
    """Extrusion: the die terms are drawing's at the punch speed (p A₀ v₀ = σ_d A_f v_f), the
    container friction is the Tresca stress m̄ k on the wall 2π R₀ L_c over the punch area, and
    k defaults to σ₀/√3; bad friction and lengths are refused."""
    from fxcontact.theory.forming import (drawing_ideal_stress, drawing_mean_strain_rate,
                                   drawing_upper_bound, extrusion_container_friction,
                                   extrusion_theory)
    a = math.radians(20.0)
    th = extrusion_theory(40.0, 0.1, 10.0, 6.0, a, 10.0, mbar_die=0.1, mbar_container=0.3,
                          container_length=12.0, land_length=1.0)
    rate = drawing_mean_strain_rate(10.0, 6.0, a, 10.0)
    s0 = float(flow_stress(40.0, 0.1, rate))
    assert th["sigma0"] == pytest.approx(s0, rel=1e-14)
    assert th["ideal"] == pytest.approx(s0 * math.log(10.0 ** 2 / 6.0 ** 2), rel=1e-14)
    assert th["ideal"] == drawing_ideal_stress(s0, 10.0, 6.0)
    assert th["avitzur"] == drawing_upper_bound(s0, 10.0, 6.0, a, 0.1, 1.0)
    k = s0 / math.sqrt(3.0)
    force = 0.3 * k * 2.0 * math.pi * 10.0 * 12.0
    assert th["container"] == pytest.approx(force / (math.pi * 10.0 ** 2), rel=1e-14)
    assert th["upper"] == th["avitzur"] + th["container"]
    assert th["extrusion_ratio"] == pytest.approx(1.0 / (1.0 - th["reduction"]))
    given = extrusion_theory(40.0, 0.1, 10.0, 6.0, a, 10.0, mbar_container=0.3,
                             container_length=12.0, shear_yield=20.0)
    assert given["container"] == pytest.approx(2 * 0.3 * 20.0 * 12.0 / 10.0, rel=1e-14)
    assert extrusion_container_friction(20.0, 0.0, 10.0, 1.0) == 0.0
    with pytest.raises(ValueError, match="mbar"):
        extrusion_container_friction(20.0, 1.0, 10.0, 1.5)
    with pytest.raises(ValueError, match="container_length"):
        extrusion_container_friction(20.0, -1.0, 10.0, 0.3)
    with pytest.raises(ValueError, match="final_radius"):
        extrusion_theory(40.0, 0.1, 6.0, 10.0, a, 10.0)


def test_every_process_theory_importable_from_forming():
    """The flat-rolling band is reachable from ``fxcontact.theory.forming`` too (one place for the
    processes' theory), the same function as ``fxcontact.theory.flat_rolling``'s."""
    from fxcontact.theory import forming
    from fxcontact.theory import flat_rolling as rolling

    assert forming.flat_rolling_theory is rolling.theory_band
    assert "flat_rolling_theory" in forming.__all__
