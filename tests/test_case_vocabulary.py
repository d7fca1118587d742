"""One vocabulary for the penalty and the friction of the six process cases
(``fxcontact.processes.contact_laws``): ``penalty`` (a ``Penalty``) and ``friction`` (a law or
a mapping tool name -> law).

For each case: the former spelling warns (a ``DeprecationWarning`` naming the new field) and
makes the same case as the new spelling; its built contact (``build(case)`` at the quick size)
holds the friction laws and resolves the penalty ρ of the former set-up, bitwise (the former
set-up's arithmetic written out here: k = ρ(β)/dt of the die processes, β at the bite's strain
rate of the bar); two spellings at once raise; the default case is the former default.
"""

import dataclasses
import math
import warnings

import pytest

from fxcontact import (Coulomb, Frictionless, NortonHoff, Norton, Penalty, Tresca,
                       penalty_from_beta)
from fxcontact.console import case_parser, parse_case
from fxcontact.processes import (BarRollingCase, DrawingCase, ExtrusionCase, FlatRollingCase,
                                 RingRollingCase, UpsettingCase, bar_rolling, build_drawing,
                                 build_extrusion, build_upsetting, flat_rolling, ring_rolling)
from fxcontact.processes.contact_laws import ToolLaws, gap_penalty

DT = 0.01   #: the increment at which the built contacts' ρ is compared


def _former(make, *fields):
    """The case of the former spelling ``make()``, which must warn naming each of ``fields``
    (a DeprecationWarning per new field)."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        case = make()
    texts = [str(w.message) for w in seen if w.category is DeprecationWarning]
    for field in fields:
        assert any(f"former spelling of {field} " in t and f"give {field}=" in t
                   for t in texts), (field, texts)
    return case


def _rho(penalty, material, rate=1.0):
    """ρ of an increment of DT (a fresh copy: the contact's own is not resolved here)."""
    return penalty.completed().rho(material, DT, lambda: rate)


def _built_rho(contact, sim, rate=1.0):
    p = contact.penalty.completed()
    p.bind("velocity", contact.element_size)
    return p.rho(sim.material, DT, lambda: rate)


def _close(s):
    s.sim.close()


# ---- the die processes: a gap stiffness from beta (k = rho(beta)/dt), one or two tools

def test_drawing():
    new = DrawingCase.quick(friction=Coulomb(0.1, mbar=1.0),
                            penalty=Penalty(beta=50.0, gap=True, reference_dt=4e-3))
    old = _former(lambda: DrawingCase.quick(mu=0.1, beta=50.0, penalty_dt=4e-3), "friction",
                  "penalty")
    assert old == new
    assert DrawingCase.quick(penalty="velocity", beta=50.0).penalty == Penalty(beta=50.0)
    assert DrawingCase(mbar=0.3).friction == Tresca(0.3)
    assert DrawingCase().friction == Frictionless()
    assert DrawingCase().penalty == Penalty(beta=100.0, gap=True)
    s = build_drawing(old)
    g, rate = s.layout, s.theory["strain_rate"]
    assert s.contact.friction == [Coulomb(0.1, mbar=1.0)]
    # the former set-up: NodalContact(gap_stiffness=rho(beta)/penalty_dt)
    k = penalty_from_beta(s.sim.material, 50.0, g.h, strain_rate=rate) / 4e-3
    assert _built_rho(s.contact, s.sim) == _rho(Penalty(gap_stiffness=k), s.sim.material)
    assert "gap stiffness from beta = 50" in s.contact.summary()
    _close(s)


def test_extrusion():
    new = ExtrusionCase.quick(friction={"container": Tresca(0.2, shear_limit=40.0),
                                        "die": Tresca(0.05)},
                              penalty=Penalty(beta=20.0, gap=True))
    old = _former(lambda: ExtrusionCase.quick(mbar_die=0.05, mbar_container=0.2,
                                              container_shear_limit=40.0, beta=20.0),
                  "friction", "penalty")
    assert old == new
    assert ExtrusionCase.quick(container="profile", mbar_container=0.1).friction == Tresca(0.1)
    assert ExtrusionCase(mbar_die=0.0, mbar_container=0.0).friction == Frictionless()
    assert ExtrusionCase().friction == {"container": Tresca(0.3), "die": Tresca(0.1)}
    assert new.theory()["shear_yield"] == 40.0
    # relative to the case's own laws: the container's law is kept
    kept = _former(lambda: new.replace(mbar_die=0.1), "friction")
    assert kept.friction == {"container": Tresca(0.2, shear_limit=40.0), "die": Tresca(0.1)}
    s = build_extrusion(old)
    assert s.contact.friction == [Tresca(0.2, shear_limit=40.0), Tresca(0.05)]
    k = penalty_from_beta(s.sim.material, 20.0, s.layout.h,
                          strain_rate=old.theory()["strain_rate"]) / old.dt
    assert _built_rho(s.contact, s.sim) == _rho(Penalty(gap_stiffness=k), s.sim.material)
    _close(s)


def test_upsetting():
    new = UpsettingCase.quick(friction=Coulomb(0.2), penalty=Penalty(beta=30.0, gap=True))
    old = _former(lambda: UpsettingCase.quick(mu=0.2, mbar=None, beta=30.0), "friction",
                  "penalty")
    assert old == new
    assert UpsettingCase(mbar=0.0).friction == Frictionless()
    assert UpsettingCase().friction == Tresca(1.0)
    s = build_upsetting(dataclasses.replace(old, remesh=False))
    assert s.contact.friction == [Coulomb(0.2)]
    k = penalty_from_beta(s.sim.material, 30.0, old.h, strain_rate=old.speed / old.H0) / old.dt
    assert _built_rho(s.contact, s.sim) == _rho(Penalty(gap_stiffness=k), s.sim.material)
    _close(s)


# ---- the rolling processes

def test_flat_rolling():
    new = FlatRollingCase(friction=Coulomb(0.25, mbar=0.8)).quick()
    old = _former(lambda: FlatRollingCase(mu=0.25, mbar=0.8), "friction").quick()
    assert old == new and FlatRollingCase().friction == Coulomb(0.3, mbar=1.0)
    assert new.friction_coefficients() == (0.25, 0.8)
    s = flat_rolling.build(old)
    assert s.roll_contact.friction == [Coulomb(0.25, mbar=0.8)]
    for c in (s.roll_contact, s.pusher_contact):   # the former default: NodalContact's beta
        assert c.penalty == Penalty() and c.penalty.as_given() == Penalty.of().as_given()
    s.sim.close()


def test_bar_rolling():
    new = BarRollingCase(friction=Norton(0.2, 0.2), penalty=Penalty(beta=20.0)).quick()
    old = _former(lambda: BarRollingCase(alpha_f=0.2, q=0.2, beta=20.0), "friction",
                  "penalty").quick()
    assert old == new
    assert BarRollingCase().friction == Norton(0.3, 0.15)
    assert BarRollingCase().penalty == Penalty(beta=10.0)
    s = bar_rolling.build(old)
    assert s.roll_contact.friction == [Norton(0.2, 0.2)]
    # the former set-up: NodalContact(beta=beta, strain_rate=the bite's, element_size=h)
    L = old.bite_length
    rate = old.v_roll / L * math.log(math.pi * old.R0 ** 2 / s.pass_geometry["A_pass"])
    for c in (s.roll_contact, s.pusher_contact):
        ref = Penalty.of(None, 20.0, None, rate)
        ref.bind("velocity", old.h)
        assert c.element_size == old.h
        assert _built_rho(c, s.sim) == ref.rho(s.sim.material, DT, lambda: 1.0)
    s.sim.close()


def test_ring_rolling():
    new = RingRollingCase(friction={"main_roll": Norton(0.5, 0.15)},
                          penalty=Penalty(gap_stiffness=5e5)).quick()
    old = _former(lambda: RingRollingCase(main_friction=("norton", 0.5, 0.15),
                                          mandrel_friction="none", gap_stiffness=5e5),
                  "friction", "penalty").quick()
    assert old == new
    assert RingRollingCase.case1(gap_stiffness=5e5).friction == new.friction
    assert RingRollingCase().friction == {"main_roll": Coulomb(0.3, mbar=0.6),
                                          "mandrel": Coulomb(0.3, mbar=0.6)}
    assert RingRollingCase().penalty == Penalty()
    idle = RingRollingCase(idle_guides=True).quick()
    s = ring_rolling.build(idle)
    # the former set-up: idle guide rolls with the mandrel's law, the cone frictionless
    law = Coulomb(0.3, mbar=0.6)
    assert s.contact.friction == [law, law, law, law]
    assert s.contact.penalty == Penalty.of(None, None, None, None)
    s.sim.close()
    s = ring_rolling.build(old)
    assert s.contact.friction == [Norton(0.5, 0.15)] + [Frictionless()] * 3
    assert _built_rho(s.contact, s.sim) == 5e5 * DT
    s.sim.close()


# ---- both spellings, the command line

@pytest.mark.parametrize("make", [
    lambda: DrawingCase(mu=0.1, friction=Tresca(0.2)),
    lambda: DrawingCase(beta=50.0, penalty=Penalty(beta=50.0)),
    lambda: DrawingCase(penalty_dt=1e-3, penalty=Penalty(beta=100.0, gap=True)),
    lambda: ExtrusionCase(mbar_die=0.2, friction=Tresca(0.2)),
    lambda: ExtrusionCase(beta=50.0, penalty=Penalty(beta=50.0, gap=True)),
    lambda: UpsettingCase(mbar=0.5, friction=Tresca(0.5)),
    lambda: UpsettingCase(beta=50.0, penalty=Penalty(beta=50.0, gap=True)),
    lambda: FlatRollingCase(mu=0.2, friction=Coulomb(0.3, mbar=1.0)),
    lambda: BarRollingCase(alpha_f=0.2, friction=Norton(0.3, 0.15)),
    lambda: BarRollingCase(beta=5.0, penalty=Penalty(beta=10.0)),
    lambda: RingRollingCase(main_friction="none", friction={"mandrel": Tresca(0.5)}),
    lambda: RingRollingCase(gap_stiffness=1e5, penalty=Penalty()),
    lambda: dataclasses.replace(DrawingCase(friction=Tresca(0.2)), mu=0.1),
    lambda: FlatRollingCase(friction=Tresca(0.5)).replace(mu=0.1, friction=Tresca(0.3)),
], ids=["drawing-mu", "drawing-beta", "drawing-penalty_dt", "extrusion-mbar_die",
        "extrusion-beta", "upsetting-mbar", "upsetting-beta", "flat-mu", "bar-alpha_f",
        "bar-beta", "ring-main_friction", "ring-gap_stiffness", "dataclasses-replace",
        "replace"])
def test_both_spellings_raise(make):
    """Two spellings at once are never silently ignored, even when they would agree (the new
    field equal to its default but given)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        with pytest.raises(ValueError, match="given at once|has no spelling"):
            make()


def test_replace_keeps_the_other_fields_and_the_defaults():
    """``dataclasses.replace`` and ``.quick()`` pass the new fields along (the default objects
    themselves); a former field beside a case's own law converts relative to it
    (``case.replace``), or is refused where the former fields cannot spell that law."""
    for case_type in (DrawingCase, ExtrusionCase, UpsettingCase):
        q = case_type.quick()
        assert q.penalty is case_type.penalty and q.friction is case_type.friction
    for case in (FlatRollingCase(), BarRollingCase(), RingRollingCase()):
        q = dataclasses.replace(case.quick(), max_increments=10)
        assert q.penalty is type(case).penalty and q.friction is type(case).friction
    case = DrawingCase(friction=Coulomb(0.1, mbar=0.5))
    assert _former(lambda: case.replace(mu=0.2), "friction").friction == Coulomb(0.2, mbar=0.5)
    with pytest.raises(ValueError, match="has no spelling in mbar, mu"):
        DrawingCase(friction=Coulomb(0.1, shear_limit=50.0)).replace(mu=0.2)
    with pytest.raises(ValueError, match="not a tool of RingRollingCase"):
        RingRollingCase(friction={"roll": Tresca(0.5)})
    with pytest.raises(ValueError, match="penalty must be a fxcontact.Penalty"):
        BarRollingCase(penalty=10.0)
    with pytest.raises(ValueError, match="mbar_container"):
        ExtrusionCase(mbar_container=1.5)
    with pytest.raises(TypeError, match="read-only"):
        ExtrusionCase().friction["die"] = Tresca(0.5)
    assert isinstance(ExtrusionCase(friction={"die": Tresca(0.5)}).friction, ToolLaws)
    assert hash(ExtrusionCase()) == hash(ExtrusionCase())


def test_command_line_options_keep_the_former_names():
    """``case_parser``/``parse_case``: ``--mu``, ``--gap_stiffness``, ``--main_friction`` set
    the new fields, without a warning (the options keep their names); the penalty and
    friction objects have no option of their own."""
    parser = case_parser(FlatRollingCase, "flat", "results")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        case, _ = parse_case(parser, FlatRollingCase, ["--quick", "--mbar", "0.7"])
    assert case.friction == Coulomb(0.3, mbar=0.7) and case.h_x == FlatRollingCase().quick().h_x
    with pytest.raises(SystemExit):
        parse_case(parser, FlatRollingCase, ["--friction", "coulomb"])
    parser = case_parser(RingRollingCase, "ring", "results")
    case, _ = parse_case(parser, RingRollingCase, ["--gap_stiffness", "2e5",
                                                   "--mandrel_friction", "none"])
    assert case.penalty == Penalty(gap_stiffness=2e5)
    assert case.friction == {"main_roll": Coulomb(0.3, mbar=0.6)}
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        case = DrawingCase().with_options(penalty="velocity", beta=40.0, mbar=0.2)
    assert case.penalty == Penalty(beta=40.0) and case.friction == Tresca(0.2)


def test_default_penalties_resolve_as_before():
    """The default cases' penalties give the former default set-ups' ρ, bitwise: k = ρ(β)/dt
    at the die's (drawing, extrusion) or the start's (upsetting) strain rate, β = 10 at the
    bite's rate (bar), NodalContact's own default (flat and ring rolling)."""
    for case, rate, h in ((DrawingCase(), DrawingCase().theory()["strain_rate"],
                           DrawingCase().h / DrawingCase().size),
                          (ExtrusionCase(), ExtrusionCase().theory()["strain_rate"],
                           ExtrusionCase().h),
                          (UpsettingCase(), UpsettingCase().speed / UpsettingCase().H0,
                           UpsettingCase().h)):
        mat = NortonHoff(K=case.K, m=case.m, regularization=1e-3 * rate)
        p = gap_penalty(case.penalty, rate, h, case.dt)
        p.bind("velocity", 123.0)          # the contact's own element size is not used
        former = Penalty(gap_stiffness=penalty_from_beta(mat, 100.0, h, strain_rate=rate)
                         / case.dt)
        for dt in (case.dt, 0.3 * case.dt):
            assert p.rho(mat, dt, None) == former.rho(mat, dt, None), type(case).__name__
    mat = NortonHoff(K=50.0, m=0.03, regularization=1e-3)
    bar = BarRollingCase().penalty.completed(strain_rate=2.5)
    former = Penalty.of(None, 10.0, None, 2.5)
    for p in (bar, former):
        p.bind("velocity", 9.0)
    assert bar.rho(mat, DT, None) == former.rho(mat, DT, None)
    for case in (FlatRollingCase(), RingRollingCase()):
        assert case.penalty.as_given() == Penalty.of(None, None, None, None).as_given()
