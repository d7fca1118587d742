"""The contracts of the objects a :class:`~fxcontact.simulation.Simulation` drives, as
:class:`typing.Protocol` classes.

A **contributor** (``Simulation.add_contributor``: :class:`~fxcontact.contact.NodalContact`,
:class:`~fxcontact.contact.springs.NodalSprings`, your own) must be a :class:`Contributor`: it adds
per-vertex residual entries and 3×3 Jacobian blocks. A **controller**
(``Simulation.add_controller``: the ring mill's :mod:`fxcontact.idle`) sets the tools' motions
between increments and has no required method. Every other method is optional; each optional
hook is a small protocol of its own (all are ``runtime_checkable``), which the simulation, its
outputs and checkpoints check with ``isinstance`` before they call it (the Newton solver,
:mod:`fxcontact.newton.solver`, looks the :class:`SolverHooks` methods up by name):

* :class:`Contributor` — ``evaluate``, ``stable``: required of every contributor;
* :class:`BeginsIncrement`, :class:`EndsIncrement`, :class:`HasDiagnostics` — contributors and
  controllers;
* :class:`HasOutputFields`, :class:`UpdatesOutputFields` — contributors (the VTK series);
* :class:`SavesState`, :class:`RestoresState` — contributors, controllers and the kinematics
  (checkpoints);
* :class:`HasSetupSignature` — contributors (checkpoints);
* :class:`HasSummary` — contributors (the run's summary);
* :class:`Remeshable` — contributors and controllers (``Simulation.remesh``);
* :class:`SolvesIncrement` — one controller at most;
* :class:`SolverHooks` — ``begin_solve``, ``fingerprint``, ``cycle_hint``, ``residual_floor``,
  ``force_norm``:
  contributors, called by the Newton solver (:func:`force_scale` and
  :func:`warn_unscaled_ftol`: the ``force_norm`` of all contributors, for
  ``SolverOptions.ftol``).

``docs/architecture.md`` ("The contributor protocol") says when each is called.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Dict, List, Protocol, runtime_checkable

if TYPE_CHECKING:   # pragma: no cover
    import numpy as np

    from fxcontact.newton.options import SolveInfo
    from fxcontact.newton.problem import NodalTerms

__all__ = ["Contributor", "Controller", "BeginsIncrement", "EndsIncrement", "HasDiagnostics",
           "HasOutputFields", "UpdatesOutputFields", "SavesState", "RestoresState",
           "HasSetupSignature", "HasSummary", "Remeshable", "SolvesIncrement",
           "SolverHooks"]


@runtime_checkable
class Contributor(Protocol):
    """Adds nodal terms to the Newton problem (required of every contributor)."""

    def evaluate(self, w, jacobian: bool) -> "NodalTerms":
        """Residual entries (and Jacobian blocks if ``jacobian``) at the iterate ``w``."""

    def stable(self) -> bool:
        """Whether the contributor's state (a contact's active set) did not change since the
        previous call (collective; Newton converges only when every contributor is stable)."""


@runtime_checkable
class Controller(Protocol):
    """A controller of the tools (``Simulation.add_controller``). No method is required: it acts
    through the optional hooks :class:`BeginsIncrement` (called before the contributors'),
    :class:`SolvesIncrement`, :class:`EndsIncrement`, :class:`HasDiagnostics` and the
    checkpoint pair :class:`SavesState` / :class:`RestoresState`."""


@runtime_checkable
class BeginsIncrement(Protocol):
    def begin_increment(self, sim, t: float, dt: float, x_t: "np.ndarray") -> None:
        """Once per increment attempt, before Newton: positions ``x_t`` at the start, the tools
        at ``t + dt``."""


@runtime_checkable
class CommitsIncrement(Protocol):
    def commit_increment(self, sim, dt: float) -> None:
        """After an accepted increment's solve, before its geometry update: on the
        configuration the increment was solved on (a controller's; the heat step)."""


@runtime_checkable
class EndsIncrement(Protocol):
    def end_increment(self, sim, dt: float) -> None:
        """After an accepted increment (before its geometry is used again)."""


@runtime_checkable
class HasDiagnostics(Protocol):
    def diagnostics(self) -> Dict[str, float]:
        """History columns of the accepted increment (collective values)."""


@runtime_checkable
class HasOutputFields(Protocol):
    def output_fields(self) -> List:
        """dolfinx Functions added to the VTK series."""


@runtime_checkable
class UpdatesOutputFields(Protocol):
    def update_output_fields(self) -> None:
        """Fill the :class:`HasOutputFields` functions before a VTK step is written."""


@runtime_checkable
class SavesState(Protocol):
    def checkpoint_state(self) -> dict:
        """The state a resumed run needs (:mod:`fxcontact.checkpoint`)."""


@runtime_checkable
class RestoresState(Protocol):
    def restore_state(self, state: dict) -> None:
        """Take back the state of :meth:`SavesState.checkpoint_state`."""


@runtime_checkable
class HasSetupSignature(Protocol):
    def setup_signature(self) -> dict:
        """Parameters as given (plain values), saved in each checkpoint: ``resume()`` refuses
        another set-up and names the parameter that differs."""


@runtime_checkable
class HasSummary(Protocol):
    def summary(self) -> str:
        """One line of the run's summary (logged at the end of ``Simulation.run``): the
        parameters resolved during the run (a contact's penalty, its friction's shear limit)."""


@runtime_checkable
class Remeshable(Protocol):
    def remesh(self, space, facet_tags) -> None:
        """Rebind to a new mesh of the body (``Simulation.remesh``): ``space`` the new
        :class:`~fxcontact.spaces.MixedSpace`, ``facet_tags`` its facet tags (the old tags on
        the new boundary). Collective. A contributor or a controller without it stops a
        remesh; a controller that keeps nothing of the mesh has one that does nothing."""


@runtime_checkable
class SolvesIncrement(Protocol):
    def solve(self, sim, begin: Callable[[], None]) -> "SolveInfo":
        """Replaces the increment's Newton solve; ``begin()`` restarts the contributors."""


@runtime_checkable
class SolverHooks(Protocol):
    """What the Newton solver (:mod:`fxcontact.newton.solver`) calls on a contributor that has it."""

    def begin_solve(self) -> None:
        """At the start of each Newton solve."""

    def fingerprint(self) -> tuple:
        """An identifier of the state, the same on every rank (cycle detection)."""

    def cycle_hint(self, period: int = 1) -> str:
        """What changes over a cycle of ``period`` Newton iterations, and the cure."""

    def residual_floor(self) -> float:
        """The round-off level of the contributor's residual norm."""

    def force_norm(self) -> float:
        """ℓ² norm of the contributor's nodal forces at the last iterate (the scale of
        ``SolverOptions.ftol``)."""
