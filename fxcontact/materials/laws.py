"""Constitutive laws in the incremental velocity setting (THEORY §1).

Each material builds the UFL residual of one increment on the current configuration for the mixed
unknown ``(v, p)``: :meth:`residual`. The numpy methods (``stress``, ``tangent``, ``potential``) are
point-wise reference implementations used in tests (finite-difference checks) and diagnostics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import ufl

__all__ = ["NortonHoff", "LinearElastic", "Material", "deviator_np"]


def _check_positive(name, value):
    if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value)
            and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def _dev(e):
    d = e.ufl_shape[0]
    return e - ufl.tr(e) / d * ufl.Identity(d)


def deviator_np(e):
    """Deviatoric part of the (..., d, d) tensors ``e`` (numpy; the reference laws)."""
    d = e.shape[-1]
    return e - np.trace(e, axis1=-2, axis2=-1)[..., None, None] / d * np.eye(d)


def _pdev_np(d):
    """The deviatoric projector on symmetric d×d tensors, I_sym − I⊗I/d (d×d×d×d)."""
    eye = np.eye(d)
    Isym = 0.5 * (np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye))
    return Isym - np.einsum("ij,kl->ijkl", eye, eye) / d


class Material:
    """Base class: marker for the materials fxcontact knows how to assemble."""

    #: Small-strain materials are solved on the fixed reference mesh with an accumulated
    #: displacement; large-strain (viscoplastic) materials use the updated-Lagrangian mesh motion.
    small_strain: bool = False

    def residual(self, v, p, w, q, dx, dt, u_prev=None):  # pragma: no cover - abstract
        raise NotImplementedError

    def linearized(self) -> "Material":
        """A linear material used to build the first Newton guess (itself if already linear)."""
        return self


@dataclass(frozen=True)
class NortonHoff(Material):
    """Incompressible Norton–Hoff viscoplasticity, ``s = 2K z^(m-1) ε̇`` (THEORY §1.1).

    The potential is regularised, ``z_r² = 2 ε̇:ε̇ + 3 ε̇₀²``, so the residual stays the exact gradient
    of a convex potential and the tangent is finite in rigid zones. The strain rate entering the
    potential is the deviator of ``ε(v)`` (THEORY §1.1 design choice: MINI enforces div v = 0 only
    weakly).

    Args:
        K: consistency [MPa·s^m], > 0.
        m: strain-rate sensitivity, 0 < m ≤ 1 (m = 1 is a Newtonian fluid of viscosity K).
        regularization: ε̇₀ [1/s], > 0; choose 1e-3–1e-4 × the characteristic strain rate.

    Nearly rigid-plastic materials (m ≲ 0.05) with contact: the tangent along the flow is
    ``2 m η`` (THEORY §1.1), so a contact penalty sized on the secant viscosity η
    (``NodalContact(beta=...)``, THEORY §2.5) is 1/m times stiffer than the material in that
    direction; Newton then stalls on nodes grazing the tool
    (``benchmarks/bench_newton_rigid_plastic.py``, drawing at m = 0.016: β = 10 instead of 1e3
    cuts the Newton iterations by 2.5–6×; ε̇₀ alone has little effect, but with β = 10,
    ε̇₀ = 1e-3 × the process strain rate instead of the default brings the increments to 6–10
    iterations). The default ε̇₀ = 1e-6 1/s is absolute: scale it to the process.
    """

    K: float
    m: float
    regularization: float = 1e-6

    small_strain = False

    def __post_init__(self):
        _check_positive("K (Norton-Hoff consistency)", self.K)
        if not (isinstance(self.m, (int, float, np.floating)) and 0.0 < self.m <= 1.0):
            raise ValueError(f"m (strain-rate sensitivity) must be in (0, 1], got {self.m!r}")
        _check_positive("regularization (reference strain rate)", self.regularization)

    # -- UFL -----------------------------------------------------------------------------
    def z_ufl(self, eps):
        e = _dev(eps)
        return ufl.sqrt(2.0 * ufl.inner(e, e) + 3.0 * self.regularization**2)

    def exponent_ufl(self):
        """The strain-rate sensitivity as it enters the UFL expressions (stress, tangents, dual
        update): ``m`` here; a subclass may return a ``dolfinx.fem.Constant`` to change it
        between increments (the bar-rolling demo's start-up exponent)."""
        return self.m

    def law_ufl(self, z):
        """(K, m) of the law at the regularised ``z`` as they enter the UFL expressions:
        ``(K, exponent_ufl())`` here; :class:`LocalNortonHoff` returns per-cell fields, chosen
        by the rate interval of ``z``."""
        return self.K, self.exponent_ufl()

    def secant_law_ufl(self, z):
        """(K, m) of the secant viscosity K z^(m−1) that weights the condensed solver's
        preconditioner: the law's own K and m (not a subclass's exponent)."""
        return self.K, self.m

    def kernel_law(self, ncells: int):
        """(K (ncells, nint), m (ncells, nint), z_nodes (nint − 1,)): the law as the
        hand-written kernels read it, per cell and per rate interval (bounds in the
        regularised z); one interval with this law's K and m."""
        return (np.full((ncells, 1), float(self.K)), np.full((ncells, 1), float(self.m)),
                np.zeros(0))

    def stress_ufl(self, eps):
        """Deviatoric stress ``s = 2 K z_r^(m-1) dev ε`` as a UFL expression."""
        z = self.z_ufl(eps)
        K, m = self.law_ufl(z)
        return 2.0 * K * z ** (m - 1.0) * _dev(eps)

    def equivalent_strain_rate_ufl(self, eps):
        """Un-regularised ε̄̇ = sqrt(2/3 dev ε : dev ε)."""
        e = _dev(eps)
        return ufl.sqrt(2.0 / 3.0 * ufl.inner(e, e))

    def residual(self, v, p, w, q, dx, dt, u_prev=None):
        eps = ufl.sym(ufl.grad(v))
        return (ufl.inner(self.stress_ufl(eps), ufl.sym(ufl.grad(w))) * dx
                + self.incompressibility_ufl(v, p, w, q, dx))

    @staticmethod
    def incompressibility_ufl(v, p, w, q, dx):
        """The pressure terms of :meth:`residual`, −p div w − q div v. They are bilinear, so
        their Jacobian is the same form of the trial functions (δv, δp)."""
        return -p * ufl.div(w) * dx - q * ufl.div(v) * dx

    # -- primal–dual Newton (fxcontact.element.dual) -------------------------------------------------
    def dual_tangent_correction_ufl(self, eps, s_dual, deps, eps_w):
        """Primal–dual tangent minus the consistent one, as the UFL integrand of a bilinear
        form (``deps`` the trial strain rate, ``eps_w`` the test one; THEORY §1.1).

        The consistent tangent is 2K z^(m−1) [P_dev − 2(1−m)/z² e⊗e], e = dev ε̇. Newton on the
        dual relation z^(1−m) s − 2K e = 0 instead of on s = 2K z^(m−1) e (the primal–dual
        Newton of total-variation problems, Chan–Golub–Mulet) replaces 2K z^(m−1) e in the
        rank-one term by the dual stress s*, symmetrised here: 2(1−m)/z² · ½(s*⊗e + e⊗s*).
        With s* equal to the primal stress the two coincide."""
        e, de, ew = _dev(eps), _dev(deps), _dev(eps_w)
        c = self._rank_one_factor(eps)
        return (c * ufl.inner(ew, self.stress_ufl(eps)) * ufl.inner(e, de)
                - self._dual_rank_one_ufl(e, s_dual, de, ew, c))

    def dual_tangent_ufl(self, eps, s_dual, deps, eps_w):
        """The whole primal–dual tangent ε̇_w : T(s*) : δε̇ as a UFL integrand,
        2K z^(m−1) dev δε̇ : dev ε̇_w − 2(1−m)/z² · ½[(ε̇_w : s*)(e : δε̇) + (ε̇_w : e)(s* : δε̇)].
        Equal to the consistent tangent's derivative plus :meth:`dual_tangent_correction_ufl`,
        at about 60 % of its kernel cost (``benchmarks/README.md``, bench_assembly)."""
        e, de, ew = _dev(eps), _dev(deps), _dev(eps_w)
        z = self.z_ufl(eps)
        K, m = self.law_ufl(z)
        return (2.0 * K * z ** (m - 1.0) * ufl.inner(de, ew)
                - self._dual_rank_one_ufl(e, s_dual, de, ew, self._rank_one_factor(eps)))

    def _rank_one_factor(self, eps):
        z = self.z_ufl(eps)
        return 2.0 * (1.0 - self.law_ufl(z)[1]) / z ** 2

    @staticmethod
    def _dual_rank_one_ufl(e, s_dual, de, ew, c):
        return 0.5 * c * (ufl.inner(ew, s_dual) * ufl.inner(e, de)
                          + ufl.inner(ew, e) * ufl.inner(s_dual, de))

    def dual_update_ufl(self, eps_old, eps_new, s_dual):
        """The dual stress after a Newton step from ε̇_old to ε̇_new, as a UFL expression: the
        linearisation of the dual relation at (ε̇_old, s*), s_p(ε̇_old) + [2K z^(m−1) P_dev −
        2(1−m)/z² s*⊗e] : dev(ε̇_new − ε̇_old), its magnitude capped at that of the primal
        stress at ε̇_new (which keeps the primal–dual tangent positive definite)."""
        e = _dev(eps_old)
        de = _dev(eps_new - eps_old)
        z = self.z_ufl(eps_old)
        K, m = self.law_ufl(z)
        s_new = (self.stress_ufl(eps_old) + 2.0 * K * z ** (m - 1.0) * de
                 - 2.0 * (1.0 - m) / z**2 * ufl.inner(e, de) * s_dual)
        sp_new = self.stress_ufl(eps_new)
        n_new = ufl.sqrt(ufl.inner(s_new, s_new))
        n_cap = ufl.sqrt(ufl.inner(sp_new, sp_new))
        return ufl.conditional(ufl.gt(n_new, n_cap), n_cap / n_new, 1.0) * s_new

    def linearized(self) -> "NortonHoff":
        """The Newtonian fluid (m = 1) of the same consistency: the start-up guess."""
        return NortonHoff(self.K, 1.0, self.regularization)

    def viscosity(self, strain_rate: float) -> float:
        """Secant viscosity η = K z^(m-1) at an equivalent strain rate (for penalty scaling)."""
        z = math.sqrt(3.0 * strain_rate**2 + 3.0 * self.regularization**2)
        return self.K * z ** (self.m - 1.0)

    def flow_stress(self, strain_rate: float) -> float:
        """Equivalent (von Mises) stress σ̄ = √3 K (√3 ε̄̇)^m."""
        return math.sqrt(3.0) * self.K * (math.sqrt(3.0) * strain_rate) ** self.m

    # -- numpy reference ------------------------------------------------------------------
    def _z(self, eps):
        e = deviator_np(eps)
        return np.sqrt(2.0 * np.einsum("...ij,...ij", e, e) + 3.0 * self.regularization**2)

    def potential(self, eps: np.ndarray) -> np.ndarray:
        """φ_r(ε) = K/(m+1) z_r^(m+1)."""
        return self.K / (self.m + 1.0) * self._z(eps) ** (self.m + 1.0)

    def stress(self, eps: np.ndarray) -> np.ndarray:
        return 2.0 * self.K * self._z(eps)[..., None, None] ** (self.m - 1.0) * deviator_np(eps)

    def dual_update(self, eps_old: np.ndarray, eps_new: np.ndarray,
                    s_dual: np.ndarray) -> np.ndarray:
        """numpy twin of :meth:`dual_update_ufl`."""
        e = deviator_np(eps_old)
        de = deviator_np(eps_new - eps_old)
        z = self._z(eps_old)[..., None, None]
        ede = np.einsum("...ij,...ij", e, de)[..., None, None]
        s_new = (self.stress(eps_old) + 2.0 * self.K * z ** (self.m - 1.0) * de
                 - 2.0 * (1.0 - self.m) / z**2 * ede * s_dual)
        sp = self.stress(eps_new)
        n_new = np.sqrt(np.einsum("...ij,...ij", s_new, s_new))[..., None, None]
        n_cap = np.sqrt(np.einsum("...ij,...ij", sp, sp))[..., None, None]
        return np.where(n_new > n_cap, n_cap / np.where(n_new > 0, n_new, 1.0), 1.0) * s_new

    def dual_tangent(self, eps: np.ndarray, s_dual: np.ndarray) -> np.ndarray:
        """The primal–dual tangent (d×d×d×d, symmetrised), numpy twin of
        :meth:`dual_tangent_ufl` (the consistent tangent plus
        :meth:`dual_tangent_correction_ufl`)."""
        e = deviator_np(eps)
        z = self._z(eps)
        sp = self.stress(eps)
        P = _pdev_np(eps.shape[-1])
        corr = 2.0 * (1.0 - self.m) / z**2 * (
            np.einsum("ij,kl->ijkl", sp, e) - 0.5 * np.einsum("ij,kl->ijkl", s_dual, e)
            - 0.5 * np.einsum("ij,kl->ijkl", e, s_dual))
        # the correction acts on deviatoric increments and is tested with deviatoric ones
        corr = np.einsum("ijab,abcd,cdkl->ijkl", P, corr, P)
        return self.tangent(eps) + corr

    def tangent(self, eps: np.ndarray) -> np.ndarray:
        """Consistent tangent ∂s/∂ε (d×d×d×d), acting on symmetric increments."""
        d = eps.shape[-1]
        e = deviator_np(eps)
        z = self._z(eps)
        Pdev = _pdev_np(d)
        return 2.0 * self.K * z ** (self.m - 1.0) * (
            Pdev + 2.0 * (self.m - 1.0) / z**2 * np.einsum("ij,kl->ijkl", e, e))


def kernel_reads_law(material) -> bool:
    """Whether the hand-written kernels read what a Norton–Hoff material's UFL law is: its
    ``law_ufl`` is NortonHoff's own, or its ``kernel_law`` is redefined with it."""
    t = type(material)
    return t.law_ufl is NortonHoff.law_ufl or t.kernel_law is not NortonHoff.kernel_law


@dataclass(frozen=True)
class LinearElastic(Material):
    """Linear isotropic elasticity in the incremental velocity setting (THEORY §1.4).

    ``u^{t+dt} = u^t + dt v``; the residual is ``∫ σ(u^{t+dt}) : ε(w)`` with the mixed pressure
    ``p = -κ div u`` (so ν → 0.5 stays well posed); the pressure equation is divided by ``dt`` so
    the Jacobian ``[[dt A, Bᵀ], [B, -M/(κ dt)]]`` is symmetric. Small strain: the mesh is not
    moved, the displacement is accumulated.

    Args:
        E: Young's modulus [MPa], > 0.
        nu: Poisson's ratio, -1 < ν < 0.5.
    """

    E: float
    nu: float

    small_strain = True

    def __post_init__(self):
        _check_positive("E (Young's modulus)", self.E)
        if not (isinstance(self.nu, (int, float, np.floating)) and -1.0 < self.nu < 0.5):
            raise ValueError(f"nu (Poisson's ratio) must be in (-1, 0.5), got {self.nu!r}")

    @property
    def mu(self) -> float:
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lmbda(self) -> float:
        return self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))

    def bulk_modulus(self, gdim: int) -> float:
        """κ such that p = -κ div u: λ + 2μ/d (d = 3; plane strain: d = 2 gives λ + μ)."""
        return self.lmbda + 2.0 * self.mu / gdim

    @property
    def plane_strain_modulus(self) -> float:
        """E* = E / (1 - ν²) (Hertz, rigid indenter)."""
        return self.E / (1.0 - self.nu**2)

    def residual(self, v, p, w, q, dx, dt, u_prev=None):
        if u_prev is None:
            raise ValueError("LinearElastic.residual needs the accumulated displacement u_prev")
        d = v.ufl_shape[0]
        kappa = self.bulk_modulus(d)
        u = u_prev + dt * v
        eps = ufl.sym(ufl.grad(u))
        s = 2.0 * self.mu * _dev(eps)
        return (ufl.inner(s, ufl.sym(ufl.grad(w))) * dx - p * ufl.div(w) * dx
                - q * (ufl.div(u) / dt + p / (kappa * dt)) * dx)

    def stress(self, eps: np.ndarray) -> np.ndarray:
        d = eps.shape[-1]
        tr = np.trace(eps, axis1=-2, axis2=-1)[..., None, None]
        return self.lmbda * tr * np.eye(d) + 2.0 * self.mu * eps
