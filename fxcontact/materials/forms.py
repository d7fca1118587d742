"""UFL pieces of the increment problem that depend on the material (THEORY §1.1, §1.4).

:class:`~fxcontact.simulation.Simulation` builds its residual from the material's own
``residual``; this module gives what the solvers need besides: the equivalent strain rate, the
secant shear viscosity and the volumetric augmentation of the condensed iterative solver's
preconditioner, and the Jacobian of the primal–dual Norton–Hoff Newton (:mod:`fxcontact.element.dual`).
"""

from __future__ import annotations

import ufl

from fxcontact.materials.laws import LinearElastic, NortonHoff

__all__ = ["equivalent_strain_rate_ufl", "shear_viscosity_ufl", "uses_dual_stress",
           "standard_norton_hoff", "volumetric_augment_ufl", "primal_dual_jacobian"]


def equivalent_strain_rate_ufl(v, gdim: int):
    """√(2/3 D':D') of the velocity ``v`` (un-regularised), D' the strain-rate deviator."""
    e = ufl.sym(ufl.grad(v))
    de = e - ufl.tr(e) / gdim * ufl.Identity(gdim)
    return ufl.sqrt(2.0 / 3.0 * ufl.inner(de, de))


def shear_viscosity_ufl(material, v, dt):
    """Secant shear viscosity of the velocity tangent (UFL) for the Schur preconditioner of
    the condensed iterative solver (:mod:`fxcontact.element.assembled`), or None if unknown:
    ``K z^(m-1)`` for Norton–Hoff, ``μ dt`` for the velocity form of linear elasticity."""
    if isinstance(material, NortonHoff):
        z = material.z_ufl(ufl.sym(ufl.grad(v)))
        K, m = material.secant_law_ufl(z)
        return K * z ** (m - 1.0)
    if isinstance(material, LinearElastic):
        return material.mu * dt
    return None


def uses_dual_stress(material, material_tangent: str) -> bool:
    """Whether ``SolverOptions.material_tangent`` asks for the primal–dual Newton with this
    material (``"auto"``: a material that has it, nonlinear)."""
    if material_tangent == "primal-dual":
        return True
    return (material_tangent == "auto" and hasattr(material, "dual_update_ufl")
            and getattr(material, "m", 1.0) < 1.0)


def standard_norton_hoff(material) -> bool:
    """Whether the material's residual is NortonHoff's own (stress, z and residual not
    redefined by a subclass), so that its primal–dual Jacobian can be written out."""
    return isinstance(material, NortonHoff) and all(
        getattr(type(material), name) is getattr(NortonHoff, name)
        for name in ("stress_ufl", "z_ufl", "residual", "incompressibility_ufl"))


def volumetric_augment_ufl(material, eta, W, wt, dx):
    """``(2/3) η div(δv) div(w) dx`` (η the secant viscosity of :func:`shear_viscosity_ufl`)
    for a material whose velocity tangent sees only the strain-rate deviator (Norton–Hoff):
    with it the velocity block of the condensed iterative solver's preconditioner is that of
    the full strain rate (``NodalNonlinearProblem(augment=)``); None for the other materials."""
    if not isinstance(material, NortonHoff):
        return None
    du, _ = ufl.split(ufl.TrialFunction(W))
    return (2.0 / 3.0) * eta * ufl.div(du) * ufl.div(wt) * dx


def primal_dual_jacobian(material, dual, F, extras, w, v, wt, q, dx):
    """The Jacobian of the primal–dual Newton (``dual``: the :class:`~fxcontact.element.dual.
    DualStress`) for the residual ``F`` = the material's residual + ``extras``, of the unknown
    ``w`` (mixed velocity–pressure Function, ``v`` its velocity) and the test functions
    ``wt``, ``q``.

    For NortonHoff's own residual the material's Jacobian is written out (the primal–dual
    tangent and the bilinear pressure terms) rather than ``ufl.derivative`` + correction: the
    same matrix at about 60 % of the kernel cost; the other terms by ``ufl.derivative``. A
    subclass that redefines the stress or the residual gets the derivative plus the
    correction."""
    dw = ufl.TrialFunction(w.function_space)
    dv, dp = ufl.split(dw)
    if standard_norton_hoff(material):
        return sum((ufl.derivative(f, w, dw) for f in extras),
                   dual.tangent_form(v, dv, wt, dx)
                   + material.incompressibility_ufl(dv, dp, wt, q, dx))
    return ufl.derivative(F, w, dw) + dual.jacobian_correction(v, dv, wt, dx)
