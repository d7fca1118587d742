"""Plastic dissipation ∫ s:D dV (fxcontact.power) of a homogeneous velocity field against the
closed form of the Norton–Hoff law (THEORY §1.1, §14.5): s:D = 2K z^(m−1) dev D : dev D with
z² = 2 dev D : dev D + 3 ε̇₀², i.e. σ̄ ε̄̇ V without regularisation."""

import math

import dolfinx
import numpy as np
import pytest
from mpi4py import MPI

import fxcontact as fx
from fxcontact import compat


def _sim(material):
    msh = dolfinx.mesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 0.5])],
                                  [4, 2, 2], dolfinx.mesh.CellType.tetrahedron)
    return fx.Simulation(fx.MixedSpace(msh), material, progress=False)


def _set_velocity(sim, L):
    """v = L x on the velocity part of sim.w (the bubble part is zero)."""
    V, V_to_W = compat.collapse(sim.space.W.sub(0))
    u = dolfinx.fem.Function(V)
    u.interpolate(lambda x: (L @ x))
    sim.w.x.array[:] = 0.0
    sim.w.x.array[V_to_W] = u.x.array
    sim.w.x.scatter_forward()


@pytest.mark.parametrize("kind", ["uniaxial", "plane_strain_shear"])
def test_homogeneous_dissipation(kind):
    K, m, e0 = 30.0, 0.3, 1e-4
    mat = fx.NortonHoff(K, m, regularization=e0)
    sim = _sim(mat)
    r = 2.5
    L = np.diag([r, -r / 2, -r / 2]) if kind == "uniaxial" else \
        np.array([[0.0, r, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    _set_velocity(sim, L)
    D = 0.5 * (L + L.T)
    dd = np.sum(D * D)                       # traceless already
    z = math.sqrt(2 * dd + 3 * e0**2)
    expected = 2 * K * z ** (m - 1) * dd * sim.volume()
    got = fx.plastic_dissipation(sim)
    assert got == pytest.approx(expected, rel=1e-10)
    # the un-regularised closed form: flow stress × equivalent strain rate × volume
    rate = math.sqrt(2.0 / 3.0 * dd)
    assert got == pytest.approx(mat.flow_stress(rate) * rate * sim.volume(), rel=1e-6)
    assert fx.PlasticDissipation(sim)() == pytest.approx(got, rel=1e-14)


def test_needs_a_deviatoric_stress():
    with pytest.raises(ValueError, match="plastic dissipation"):
        fx.PlasticDissipation(_sim(fx.LinearElastic(2e5, 0.3)))
