"""One vocabulary for the contact of every process case: ``penalty`` (a
:class:`fxcontact.Penalty`) and ``friction`` (a law of :mod:`fxcontact.contact.friction`, or a
mapping tool name → law where a process has several tools), and their former spellings,
accepted for one release.

Every case (:class:`~fxcontact.processes.common.CaseBase` and
:class:`~fxcontact.processes.monitor.RunNumerics` are :class:`ContactLaws`) declares ``FORMER``:
for each new field the former fields (dataclass ``InitVar`` s defaulting to :data:`UNSET`, so
that they are not stored), their former defaults and the conversions both ways
(:class:`Former`). In the case's ``__post_init__``, :meth:`ContactLaws.resolve_contact_laws`
turns former fields given explicitly into the new field with a ``DeprecationWarning`` naming it,
refuses a former field beside the new one (``ValueError``: two spellings at once are never
silently ignored) and checks the new fields. :meth:`ContactLaws.replace` converts former fields
relative to the case's own law (``case.replace(mbar_die=0.2)`` keeps the container's law):
``dataclasses.replace`` passes the case's law along with the former field, which is accepted
only when that law is the class's default (the very object), refused otherwise.
:meth:`ContactLaws.with_options` does the same without a warning for a command line whose options
keep their former names (``--mu``, ``--main_friction``).
"""

from __future__ import annotations

import dataclasses
import math
import types
import warnings
from dataclasses import dataclass
from typing import Callable, Dict, Mapping, Optional, Tuple, Union

from fxcontact.contact.friction import Coulomb, FrictionLaw, Frictionless, Norton, Tresca
from fxcontact.contact.penalty import Penalty

__all__ = ["UNSET", "Friction", "ToolLaws", "Former", "former_beta_gap_penalty", "ContactLaws", "resolve_contact_laws",
           "replace_case", "gap_penalty", "contact_friction", "law_text"]


class _Unset:
    """The default of a former field: not given."""

    _instance = None

    def __new__(cls):
        if cls._instance is None:
            cls._instance = super().__new__(cls)
        return cls._instance

    def __repr__(self):
        return "UNSET"

    def __reduce__(self):
        return (_Unset, ())


#: the default of a former field of a case: not given
UNSET = _Unset()

#: what a case's ``friction`` holds: one law for every tool, or ``{tool name: law}``
Friction = Union[FrictionLaw, Mapping[str, FrictionLaw]]


class ToolLaws(dict):
    """A read-only ``{tool name: friction law}`` (hashable: a field of a frozen case); tools
    left out are frictionless."""

    def _read_only(self, *args, **kwargs):
        raise TypeError("the friction laws of a case are read-only: give a new mapping "
                        "(case.replace(friction={...}))")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _read_only
    __ior__ = _read_only

    def __hash__(self):
        return hash(tuple(sorted(self.items(), key=lambda kv: kv[0])))

    def __reduce__(self):
        return (ToolLaws, (dict(self),))


@dataclass(frozen=True)
class Former:
    """The former fields of one new field (``"penalty"`` or ``"friction"``) of a case.

    Attributes:
        field: the new field.
        defaults: each former field and its former default (a former field may have the new
            field's name: the drawing's ``penalty="gap"``, recognised by not being a
            :class:`~fxcontact.Penalty`).
        to_new: ``to_new(case, values)``: the new field's value of the former ``values`` (all of
            them; ``case`` gives the other fields), ``ValueError`` naming a bad former field.
        from_new: ``from_new(case, value)``: the former values of a new value (for
            :func:`replace_case`; checked by converting them back).
    """

    field: str
    defaults: Mapping[str, object]
    to_new: Callable[[object, Dict[str, object]], object]
    from_new: Callable[[object, object], Dict[str, object]]


def _gap_penalty_of_beta(case, v: dict) -> Penalty:
    if not (isinstance(v["beta"], (int, float)) and math.isfinite(v["beta"]) and v["beta"] > 0):
        raise ValueError(f"beta must be a finite number > 0, got {v['beta']!r}")
    return Penalty(beta=float(v["beta"]), gap=True)


def _beta_of_gap_penalty(case, p: Penalty) -> Optional[dict]:
    return {"beta": p.beta} if p.beta is not None else None


def former_beta_gap_penalty(default_beta: float) -> Former:
    """The former ``beta`` field of a case whose penalty is a gap stiffness from β
    (``Penalty(beta, gap=True)``: extrusion, upsetting)."""
    return Former("penalty", {"beta": default_beta}, _gap_penalty_of_beta, _beta_of_gap_penalty)


def _is_new(field: str, value) -> bool:
    if field == "penalty":
        return isinstance(value, Penalty)
    return value is None or isinstance(value, (FrictionLaw, Mapping))


def _names(given) -> str:
    return ", ".join(sorted(given))


def _both(cls, spec: Former, given, value) -> str:
    return (f"{cls.__name__}: {_names(given)} (the former spelling of {spec.field}) and "
            f"{spec.field}={value!r} given at once: give {spec.field}= only (with "
            f"dataclasses.replace, a case whose {spec.field} is not the default takes "
            f"{spec.field}=, or case.replace(...) converts the former fields)")


def _deprecated(cls, spec: Former, given, value, stacklevel: int):
    warnings.warn(f"{cls.__name__}: {_names(given)} {'is' if len(given) == 1 else 'are'} the "
                  f"former spelling of {spec.field} (accepted for one release): give "
                  f"{spec.field}={value!r}", DeprecationWarning, stacklevel=stacklevel + 1)


def _normal(case, field: str, value):
    """The new field checked: a Penalty; a law, or a mapping of the case's tools to laws
    (a :class:`ToolLaws`; None: frictionless)."""
    if field == "penalty":
        if not isinstance(value, Penalty):
            raise ValueError(f"penalty must be a fxcontact.Penalty (e.g. Penalty(beta=100.0), "
                             f"Penalty(gap_stiffness=5e5)), got {value!r}")
        return value
    if value is None:
        return Frictionless()
    if isinstance(value, FrictionLaw):
        return value
    if not isinstance(value, Mapping):
        raise ValueError(f"friction must be a friction law (Coulomb, Tresca, Norton, "
                         f"Frictionless) or a mapping tool name -> law, got {value!r}")
    tools = type(case).FRICTION_TOOLS
    for name, law in value.items():
        if tools and name not in tools:
            raise ValueError(f"friction given for '{name}', which is not a tool of "
                             f"{type(case).__name__} (its tools: {', '.join(tools)})")
        if not isinstance(law, FrictionLaw):
            raise ValueError(f"friction of '{name}' must be a friction law (Coulomb, Tresca, "
                             f"Norton, Frictionless), got {law!r}")
    return value if isinstance(value, ToolLaws) else ToolLaws(value)


def resolve_contact_laws(case, former: Mapping[str, object], stacklevel: int = 4):
    """Set ``case.penalty`` and ``case.friction`` (a frozen case, in its ``__post_init__``)
    from themselves and the ``former`` fields given (:class:`Former`): a former field given
    explicitly is converted with a ``DeprecationWarning`` naming the new field; beside a new
    field that is not the class's default object, ``ValueError``; the new fields checked."""
    cls = type(case)
    for spec in cls.FORMER:
        value, default = getattr(case, spec.field), getattr(cls, spec.field)
        given = {k: v for k, v in former.items() if k in spec.defaults and v is not UNSET}
        if spec.field in spec.defaults and not _is_new(spec.field, value):
            given[spec.field], value = value, default
        if given:
            if value is not default:
                raise ValueError(_both(cls, spec, given, value))
            value = spec.to_new(case, {**spec.defaults, **given})
            _deprecated(cls, spec, given, value, stacklevel)
        object.__setattr__(case, spec.field, value)
    for field in ("penalty", "friction"):
        if field in getattr(cls, "__dataclass_fields__", {}):
            object.__setattr__(case, field, _normal(case, field, getattr(case, field)))


def replace_case(case, changes: Mapping[str, object], warn: bool = True,
                 stacklevel: int = 2):
    """``dataclasses.replace(case, **changes)`` with the former fields among ``changes``
    converted relative to the case's own penalty and friction (their former values, checked
    by converting them back: a law the former fields cannot spell is refused with a
    ``ValueError``), with a ``DeprecationWarning`` if ``warn``."""
    changes, cls = dict(changes), type(case)
    for spec in cls.FORMER:
        given = {k: changes.pop(k) for k in list(changes)
                 if k in spec.defaults and (k != spec.field
                                            or not _is_new(spec.field, changes[k]))}
        given = {k: v for k, v in given.items() if v is not UNSET}
        if not given:
            continue
        if spec.field in changes:
            raise ValueError(_both(cls, spec, given, changes[spec.field]))
        current = getattr(case, spec.field)
        values = spec.from_new(case, current)
        if values is None or spec.to_new(case, values) != current:
            raise ValueError(f"{cls.__name__}: this case's {spec.field} {current!r} has no "
                             f"spelling in {_names(spec.defaults)}: give {spec.field}= "
                             f"instead of {_names(given)}")
        fields = {f.name: getattr(case, f.name) for f in dataclasses.fields(case)}
        value = spec.to_new(types.SimpleNamespace(**{**fields, **changes}), {**values, **given})
        if warn:
            _deprecated(cls, spec, given, value, stacklevel)
        changes[spec.field] = value
    return dataclasses.replace(case, **changes)


class ContactLaws:
    """The penalty and friction fields of a process case and their former spellings (the
    module's docstring): the base of :class:`~fxcontact.processes.common.CaseBase` and
    :class:`~fxcontact.processes.monitor.RunNumerics`."""

    #: the former spellings of ``penalty`` and ``friction`` (:class:`Former`)
    FORMER: Tuple[Former, ...] = ()
    #: the names of the process's tools (the keys a friction mapping may have)
    FRICTION_TOOLS: Tuple[str, ...] = ()

    def resolve_contact_laws(self, **former):
        """In ``__post_init__``: :func:`resolve_contact_laws` with the case's former fields."""
        resolve_contact_laws(self, former, stacklevel=5)

    def replace(self, **changes):
        """A copy with ``changes`` (checked); former fields (``mu=``, ``beta=``, …) are
        converted relative to this case's penalty and friction, with a
        ``DeprecationWarning``."""
        return replace_case(self, changes, stacklevel=3)

    def with_options(self, **options):
        """A copy with the fields of a command line: options named after former fields
        (``--mu``, ``--main_friction``) set the new field, relative to this case's law, without
        a warning (the command line keeps those names)."""
        return replace_case(self, options, warn=False)

    def tool_friction(self, tool: str) -> FrictionLaw:
        """The friction law of the tool named ``tool`` (frictionless if the mapping leaves it
        out)."""
        f = getattr(self, "friction")
        return f if isinstance(f, FrictionLaw) else f.get(tool, Frictionless())


def gap_penalty(penalty: Penalty, strain_rate: float, element_size: float,
                reference_dt: float) -> Penalty:
    """The penalty a process gives its contact when its default is a gap stiffness from β
    (drawing, extrusion, upsetting): a ``Penalty(beta=..., gap=True)`` takes the process's
    representative ``strain_rate``, ``element_size`` and ``reference_dt`` where it gives none
    (:meth:`Penalty.completed`); any other penalty is passed as given."""
    if penalty.gap:
        return penalty.completed(strain_rate, element_size, reference_dt)
    return penalty


def contact_friction(friction: Friction):
    """``friction`` as :class:`~fxcontact.NodalContact` takes it: a law, or a plain dict."""
    return dict(friction) if isinstance(friction, Mapping) else friction


def law_text(law) -> str:
    """A law (or a mapping of laws) in a report's words: ``Coulomb mu 0.3, mbar 0.6``."""
    if isinstance(law, Mapping):
        return "; ".join(f"{name} {law_text(v)}" for name, v in law.items())
    if isinstance(law, Coulomb):
        return f"Coulomb mu {law.mu:g}" + (f", mbar {law.mbar:g}" if law.mbar is not None
                                           else "")
    if isinstance(law, Tresca):
        return f"Tresca mbar {law.mbar:g}"
    if isinstance(law, Norton):
        return f"Norton alpha_f {law.alpha_f:g}, q {law.q:g}"
    return "frictionless"
