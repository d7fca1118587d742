"""Flow-stress laws (fxcontact.materials.flow): the pieces against each law's own formula, the
rate sensitivity against finite differences, the Norton–Hoff form of the pieces (stress and
tangent of THEORY §1.1), the table's interpolation, clamping and CSV input, the parameter checks
and the flow-curve picture. Pure numpy, no dolfinx object."""

import math
import warnings

import numpy as np
import pytest

from fxcontact.io.flow_curves import plot_flow_curves
from fxcontact.materials import NortonHoff
from fxcontact.materials.flow import (HanselSpittel, PowerHardening, TabulatedFlowStress,
                                      check_temperature, interval_of, norton_hoff_pieces)

STRAINS = np.array([0.0, 0.05, 0.2, 0.5])
RATES = np.array([0.01, 0.1, 1.0, 10.0])
TEMPS = np.array([900.0, 1000.0, 1100.0])


def sampled(fun, strains=STRAINS, rates=RATES, temps=TEMPS):
    e, r, t = np.meshgrid(strains, rates, temps, indexing="ij")
    return TabulatedFlowStress(strains, rates, temps, fun(e, r, t))


def hardening(e, r, t):
    """Power hardening in ε̄, a power law in the rate, linear in T [MPa]."""
    return 120.0 * (0.02 + e) ** 0.2 * r ** 0.13 * (2.0 - t / 1000.0)


def bilinear(e, r, t):
    """Linear in ε̄ and in T, a power law in the rate: the table reproduces it everywhere."""
    return (100.0 + 80.0 * e) * r ** 0.12 * (1.6 - t / 1000.0)


def laws():
    """(law, strains, temperatures) of each kind, states inside and outside a table."""
    e = np.array([0.0, 0.01, 0.1, 0.3, 0.5, 0.9, 1.5])
    t = np.array([850.0, 900.0, 950.0, 1000.0, 1060.0, 1100.0, 1250.0])
    hs = {"A": 1500.0, "m1": -0.0025, "m2": -0.06, "m3": 0.12, "m4": -0.01, "m5": 0.0002,
          "m7": 0.3, "m8": 1e-4}
    table = sampled(hardening)
    single = TabulatedFlowStress([0.2], RATES, [1000.0], hardening(0.2, RATES, 1000.0)[None, :,
                                                                                      None])
    return {
        "power": (PowerHardening(50.0, 0.15, 0.2, 0.01), e, None),
        "norton-hoff": (PowerHardening(50.0, 0.15), e, None),
        "hansel-spittel": (HanselSpittel(**hs), e, t),
        "hansel-spittel-m9": (HanselSpittel(**hs, m9=0.2), e, t),
        "hansel-spittel-no-T": (HanselSpittel(800.0, 0.0, 0.1, 0.15, m7=-0.2), e, None),
        "table": (table, e, t),
        "table-single": (single, e, None),
        "table-two-rates": (sampled(hardening, rates=np.array([0.1, 10.0])), e, t),
    }


LAWS = laws()


def test_interval_of_matches_the_definition():
    nodes = np.array([0.1, 1.0, 10.0])
    rates = np.array([0.0, 0.05, 0.1, 0.5, 1.0, 9.99, 10.0, 1e3])
    assert interval_of(rates, nodes).tolist() == [0, 0, 1, 1, 2, 2, 3, 3]
    assert interval_of(np.array([3.0, 0.0]), np.empty(0)).tolist() == [0, 0]


@pytest.mark.parametrize("name", list(LAWS))
def test_pieces_reproduce_sigma0(name):
    law, e, t = LAWS[name]
    C, m = law.pieces(e, t)
    nint = law.rate_nodes.size + 1
    assert C.shape == m.shape == (e.size, nint)
    rates = np.union1d(np.geomspace(1e-5, 1e4, 37), law.rate_nodes)
    seen = set()
    for r in rates:
        j = interval_of(r, law.rate_nodes)
        seen.add(int(j))
        ref = law.sigma0(e, r, t)
        assert np.all(ref > 0)
        np.testing.assert_allclose(C[:, j] * r ** m[:, j], ref, rtol=1e-12, atol=0)
    assert seen == set(range(nint))
    np.testing.assert_array_equal(law.sigma0(e, 0.0, t), 0.0)    # m_loc > 0: σ0 → 0
    # a scalar temperature is broadcast to the states
    if law.uses_temperature:
        C1, m1 = law.pieces(e, 1000.0)
        np.testing.assert_allclose(C1[:, 0] * 2.0 ** m1[:, 0], law.sigma0(e, 2.0, 1000.0),
                                   rtol=1e-12)


def _rates_off_nodes(law):
    """Rates away from the rate nodes: each interval's geometric middle and beyond both ends."""
    nodes = law.rate_nodes
    if nodes.size == 0:
        return np.array([1e-3, 0.3, 50.0])
    mids = np.sqrt(nodes[1:] * nodes[:-1])
    return np.concatenate([[nodes[0] / 30.0], mids, [nodes[-1] * 30.0]])


@pytest.mark.parametrize("name", list(LAWS))
def test_rate_sensitivity_is_dlnsigma_dlnrate(name):
    law, e, t = LAWS[name]
    _, m = law.pieces(e, t)
    h = 1e-5
    for r in _rates_off_nodes(law):
        fd = (np.log(law.sigma0(e, r * math.exp(h), t))
              - np.log(law.sigma0(e, r * math.exp(-h), t))) / (2 * h)
        mloc = law.rate_sensitivity(e, r, t)
        assert np.all(mloc > 0)
        np.testing.assert_allclose(mloc, fd, rtol=1e-7)
        np.testing.assert_allclose(m[:, interval_of(r, law.rate_nodes)], mloc, rtol=1e-12)


def _dev(a):
    return a - np.trace(a) / 3.0 * np.eye(3)


def _pdev():
    eye = np.eye(3)
    isym = 0.5 * (np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye))
    return isym - np.einsum("ij,kl->ijkl", eye, eye) / 3.0


def _nh_stress(law, strain, temperature, d):
    """s = 2 K z^(m−1) dev ε̇ with the piece of the current rate (THEORY §1.1), one state."""
    K, m = norton_hoff_pieces(law, np.array([strain]), temperature)
    e = _dev(d)
    z = math.sqrt(2.0 * np.sum(e * e))
    j = interval_of(z / math.sqrt(3.0), law.rate_nodes)
    return 2.0 * K[0, j] * z ** (m[0, j] - 1.0) * e, K[0, j], m[0, j], z


@pytest.mark.parametrize("name", list(LAWS))
def test_norton_hoff_pieces_stress_and_tangent(name):
    law, strains, temps = LAWS[name]
    rng = np.random.default_rng(7)
    targets = _rates_off_nodes(law)
    for k in range(12):
        strain = strains[k % strains.size]
        t = None if temps is None else temps[k % temps.size]
        a = rng.normal(size=(3, 3))
        d = a + a.T
        e = _dev(d)
        d *= targets[k % targets.size] / math.sqrt(2.0 / 3.0 * np.sum(e * e))   # ε̄̇ on target
        s, K, m, z = _nh_stress(law, strain, t, d)
        rate = z / math.sqrt(3.0)
        ref = float(law.sigma0(strain, rate, t))
        assert math.sqrt(1.5 * np.sum(s * s)) == pytest.approx(ref, rel=1e-12)
        # s = (2/3) σ0/ε̄̇ dev ε̇ (THEORY §1.1 with the flow stress)
        np.testing.assert_allclose(s, 2.0 / 3.0 * ref / rate * _dev(d), rtol=1e-12, atol=0)
        e = _dev(d)
        tangent = 2.0 * K * z ** (m - 1.0) * (
            _pdev() + 2.0 * (m - 1.0) / z**2 * np.einsum("ij,kl->ijkl", e, e))
        b = rng.normal(size=(3, 3))
        delta = b + b.T
        h = 1e-6 * np.linalg.norm(d)
        fd = (_nh_stress(law, strain, t, d + h * delta)[0]
              - _nh_stress(law, strain, t, d - h * delta)[0]) / (2 * h)
        lin = np.einsum("ijkl,kl->ij", tangent, delta)
        np.testing.assert_allclose(fd, lin, rtol=1e-6, atol=1e-7 * np.abs(lin).max())


@pytest.mark.parametrize("name", list(LAWS))
def test_norton_hoff_consistency_is_the_pieces(name):
    law, e, t = LAWS[name]
    C, m = law.pieces(e, t)
    K, mk = norton_hoff_pieces(law, e, t)
    np.testing.assert_array_equal(mk, m)
    np.testing.assert_allclose(K * 3.0 ** ((1.0 + m) / 2.0), C, rtol=1e-14)


def test_power_hardening_without_hardening_is_norton_hoff():
    for K0, m in ((50.0, 0.15), (445.0, 0.016), (2.0, 1.0)):
        law, nh = PowerHardening(K0, m), NortonHoff(K0, m)
        for rate in (1e-4, 0.03, 1.0, 7.5, 300.0):
            for strain in (0.0, 0.4, 3.0):
                assert float(law.sigma0(strain, rate)) == pytest.approx(nh.flow_stress(rate),
                                                                        rel=1e-14)
        K, mk = norton_hoff_pieces(law, np.array([0.0, 0.7]))
        assert np.all(K == K0) and np.all(mk == m)          # bit for bit
    assert not PowerHardening(50.0, 0.1).uses_temperature
    assert PowerHardening(50.0, 0.1).clamped([0.0, 10.0]) == 0
    law = PowerHardening(50.0, 0.15, 0.2, 0.01)
    assert float(law.sigma0(0.3, 2.0)) == pytest.approx(
        math.sqrt(3) * 50.0 * 0.31**0.2 * (math.sqrt(3) * 2.0) ** 0.15, rel=1e-14)


def test_hansel_spittel_floor_and_formula():
    law = HanselSpittel(1500.0, -0.0025, -0.06, 0.12, -0.01, 0.0002, 0.3, 1e-4, 0.2,
                        strain_floor=2e-3)
    T, r = 1000.0, 3.0
    at_floor = law.sigma0(2e-3, r, T)
    assert law.sigma0(0.0, r, T) == at_floor and law.sigma0(1e-3, r, T) == at_floor
    assert law.clamped([0.0, 1e-4, 5.0], T) == 0           # floored, not clamped
    e = 0.4
    ref = (1500.0 * math.exp(-0.0025 * T) * e**-0.06 * r**0.12 * math.exp(-0.01 / e)
           * (1 + e) ** (0.0002 * T) * math.exp(0.3 * e) * r ** (1e-4 * T) * T**0.2)
    assert float(law.sigma0(e, r, T)) == pytest.approx(ref, rel=1e-13)
    assert float(law.rate_sensitivity(e, r, T)) == pytest.approx(0.12 + 1e-4 * T, rel=1e-15)
    assert law.uses_temperature
    assert not HanselSpittel(800.0, 0.0, 0.1, 0.15).uses_temperature
    with pytest.raises(ValueError, match="temperature"):
        law.sigma0(e, r, None)


def test_hansel_spittel_refuses_non_positive_rate_sensitivity_and_temperature():
    law = HanselSpittel(1500.0, -0.0025, 0.1, 0.05, m8=-1e-4)     # m_loc <= 0 from 500 °C on
    assert float(law.rate_sensitivity(0.2, 1.0, 400.0)) == pytest.approx(0.01)
    for call in (lambda: law.sigma0(0.2, 1.0, [400.0, 600.0]),
                 lambda: law.rate_sensitivity(0.2, 1.0, 600.0),
                 lambda: law.pieces([0.2, 0.3], 500.0)):
        with pytest.raises(ValueError, match=r"m_loc.*T >= 500 °C.*m3 = 0\.05.*m8"):
            call()
    with pytest.raises(ValueError, match="m_loc"):
        HanselSpittel(1500.0, 0.0, 0.1, 0.0)                   # m3 <= 0, m8 = 0: never convex
    hot = HanselSpittel(1500.0, -0.0025, 0.1, 0.1, m9=0.3)
    for T in (0.0, -20.0):
        with pytest.raises(ValueError, match="m9.*T > 0 °C"):
            hot.sigma0(0.2, 1.0, T)
    with pytest.raises(ValueError, match="absolute zero"):
        hot.pieces([0.2], -300.0)


def test_table_is_exact_at_grid_points_and_for_a_bilinear_law():
    table = sampled(hardening)
    e, r, t = np.meshgrid(STRAINS, RATES, TEMPS, indexing="ij")
    np.testing.assert_allclose(table.sigma0(e, r, t), table.stress, rtol=1e-13)
    C, m = table.pieces(e.ravel(), t.ravel())
    j = interval_of(r.ravel(), table.rate_nodes)
    rows = np.arange(j.size)
    np.testing.assert_allclose(C[rows, j] * r.ravel() ** m[rows, j], table.stress.ravel(),
                               rtol=1e-13)
    np.testing.assert_allclose(m, 0.13, rtol=1e-12)            # a power law in the rate
    assert table.rate_nodes.tolist() == RATES[1:-1].tolist()
    # linear in ε̄ and T, power law in the rate: reproduced everywhere inside, and beyond the
    # tabulated rates (the end power laws extended)
    exact = sampled(bilinear)
    rng = np.random.default_rng(3)
    es = rng.uniform(0.0, 0.5, 200)
    rs = 10.0 ** rng.uniform(-4.0, 3.0, 200)
    ts = rng.uniform(900.0, 1100.0, 200)
    np.testing.assert_allclose(exact.sigma0(es, rs, ts), bilinear(es, rs, ts), rtol=1e-12)
    np.testing.assert_allclose(exact.rate_sensitivity(es, rs, ts), 0.12, rtol=1e-11)
    assert exact.clamped(es, ts) == 0


def test_table_clamps_strain_and_temperature_and_counts():
    table = sampled(hardening)
    e = np.array([0.1, 0.8, 0.1, 0.9, 0.3])
    t = np.array([950.0, 1000.0, 700.0, 1300.0, 1100.0])
    assert table.clamped(e, t) == 3
    np.testing.assert_allclose(table.sigma0(e, 2.0, t)[1:4],
                               table.sigma0([0.5, 0.1, 0.5], 2.0, [1000.0, 900.0, 1100.0]),
                               rtol=1e-14)
    single = LAWS["table-single"][0]
    assert not single.uses_temperature and single.clamped([0.0, 3.0], 20.0) == 0
    assert single.sigma0(0.0, 1.0) == single.sigma0(3.0, 1.0, 500.0)
    p = table.parameters()
    assert all(isinstance(v, (float, str)) for v in p.values())
    assert p == sampled(hardening).parameters()
    assert p != sampled(lambda e, r, t: 1.0001 * hardening(e, r, t)).parameters()


def _write_csv(path, table, order=("stress", "temperature", "strain", "strain_rate"),
               drop=(), extra_rows=(), header=None):
    e, r, t = np.meshgrid(table.strains, table.rates, table.temperatures, indexing="ij")
    cols = {"strain": e.ravel(), "strain_rate": r.ravel(), "temperature": t.ravel(),
            "stress": table.stress.ravel()}
    data = np.column_stack([cols[c] for c in order])
    data = np.delete(data, list(drop), axis=0)
    if len(extra_rows):
        data = np.vstack([data, extra_rows])
    data = data[np.random.default_rng(1).permutation(len(data))]
    with open(path, "w") as f:
        f.write("# flow stress, MPa\n" + (header or ",".join(order)) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.17g")
    return path


def test_csv_round_trip(tmp_path):
    table = sampled(hardening)
    back = TabulatedFlowStress.from_csv(_write_csv(tmp_path / "t.csv", table))
    for name in ("strains", "rates", "temperatures", "stress"):
        np.testing.assert_array_equal(getattr(back, name), getattr(table, name))
    assert back.parameters() == table.parameters()


def _raw(strains=STRAINS, rates=RATES, temps=TEMPS, fun=hardening):
    """A table-like object that bypasses the checks, to write bad CSVs."""
    class Raw:
        pass
    raw = Raw()
    raw.strains, raw.rates, raw.temperatures = strains, rates, temps
    e, r, t = np.meshgrid(strains, rates, temps, indexing="ij")
    raw.stress = fun(e, r, t)
    return raw


BAD_CSV = {
    "hole": ({"drop": [5]}, "holes.*missing"),
    "duplicate": ({"extra_rows": [[50.0, 1000.0, 0.2, 1.0]]}, "duplicate point"),
    "rate": ({"table": _raw(fun=lambda e, r, t: hardening(e, r, t) * np.where(r == 1.0, 2, 1))},
             "increase strictly with the rate"),
    "negative": ({"table": _raw(fun=lambda e, r, t: np.where(e == 0.2, -hardening(e, r, t),
                                                               hardening(e, r, t)))},
                 "stress must be > 0"),
    "extra": ({"order": ("stress", "temperature", "strain", "strain_rate", "strain"),
                   "header": "stress,temperature,strain,strain_rate,grain"}, "extra column"),
    "one-rate": ({"table": _raw(rates=np.array([1.0]))}, "at least 2 rates"),
    "pascal": ({"table": _raw(fun=lambda e, r, t: 1e6 * hardening(e, r, t))}, "Pa.*MPa"),
    "absolute-zero": ({"table": _raw(temps=np.array([-300.0, 20.0]))}, "absolute zero"),
    "text": ({"extra_rows": [[np.nan, 1000.0, 0.2, 1.0]]}, "non-finite"),
}


@pytest.mark.parametrize("case", list(BAD_CSV))
def test_bad_csv_is_refused(tmp_path, case):
    kw, match = BAD_CSV[case]
    kw = dict(kw)
    table = kw.pop("table", sampled(hardening))
    path = _write_csv(tmp_path / f"{case}.csv", table, **kw)
    with pytest.raises(ValueError, match=match):
        TabulatedFlowStress.from_csv(path)


def test_kelvin_temperatures_warn(tmp_path):
    kelvin = _raw(temps=TEMPS + 1273.15, fun=lambda e, r, t: bilinear(e, r, 0.0) * 1e3 / t)
    path = _write_csv(tmp_path / "kelvin.csv", kelvin)
    with pytest.warns(UserWarning, match="kelvin"):
        TabulatedFlowStress.from_csv(path)
    with pytest.warns(UserWarning, match="°C"):
        check_temperature([20.0, 2500.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_temperature([-273.15, 1999.0])


PH = {"K0": 50.0, "m": 0.1}
HS = {"A": 5.0, "m1": 0.0, "m2": 0.1, "m3": 0.1}
TAB = {"strains": [0.0], "rates": [0.1, 1.0], "temperatures": [20.0], "stress": [[[1.0], [2.0]]]}
BAD_PARAMETERS = [
    (PowerHardening, {**PH, "K0": float("nan")}, r"K0.*MPa·s\^m.*nan"),
    (PowerHardening, {**PH, "K0": -1.0}, r"K0.*> 0"),
    (PowerHardening, {**PH, "K0": "50"}, r"K0.*'50'"),
    (PowerHardening, {**PH, "m": 0.0}, r"m \(strain-rate sensitivity\)"),
    (PowerHardening, {**PH, "m": 1.5}, r"m \(strain-rate sensitivity\)"),
    (PowerHardening, {**PH, "m": True}, r"m \(strain-rate sensitivity\)"),
    (PowerHardening, {**PH, "n": -0.1}, r"n \(hardening exponent\)"),
    (PowerHardening, {**PH, "n": 0.2}, r"eps0 must be > 0 when n > 0.*would be 0"),
    (PowerHardening, {**PH, "n": 0.2, "eps0": float("inf")}, r"eps0.*finite"),
    (HanselSpittel, {**HS, "A": float("nan")}, r"A.*MPa.*nan"),
    (HanselSpittel, {**HS, "A": -5.0}, r"A must be > 0"),
    (HanselSpittel, {**HS, "m1": "x"}, r"m1.*1/°C.*'x'"),
    (HanselSpittel, {**HS, "m8": float("inf")}, r"m8.*1/°C"),
    (HanselSpittel, {**HS, "strain_floor": 0.0}, r"strain_floor"),
    (HanselSpittel, {**HS, "m3": None}, r"m3.*None"),
    (TabulatedFlowStress, {**TAB, "rates": [1.0, 0.1]}, "rates must be strictly increasing"),
    (TabulatedFlowStress, {**TAB, "strains": [np.nan]}, r"strains must be finite \[-\]"),
    (TabulatedFlowStress, {**TAB, "rates": [0.0, 1.0]}, r"rates must be > 0 \[1/s\]"),
    (TabulatedFlowStress, {**TAB, "stress": np.ones((2, 2, 1))}, "shape"),
    (TabulatedFlowStress, {**TAB, "stress": [[[1.0], [np.inf]]]}, r"stress must be finite \[MPa\]"),
]


@pytest.mark.parametrize("cls, kwargs, match", BAD_PARAMETERS)
def test_bad_parameters(cls, kwargs, match):
    with pytest.raises(ValueError, match=match):
        cls(**kwargs)


def test_bad_states():
    law = LAWS["power"][0]
    with pytest.raises(ValueError, match=r"strain rate.*>= 0 \[1/s\]"):
        law.sigma0(0.1, -1.0)
    with pytest.raises(ValueError, match=r"strain ε̄ must be >= 0"):
        law.pieces([-0.1, 0.2])
    with pytest.raises(ValueError, match="finite"):
        LAWS["table"][0].sigma0(0.1, 1.0, np.nan)


@pytest.mark.parametrize("name", ["power", "hansel-spittel", "table", "table-single"])
def test_plot_flow_curves(tmp_path, name):
    law = LAWS[name][0]
    path = tmp_path / f"{name}.png"
    temps = [900.0, 1100.0] if name == "hansel-spittel" else None
    plot_flow_curves(law, str(path), strain_max=0.8, temperatures=temps)
    assert path.stat().st_size > 10_000


def test_plot_flow_curves_needs_temperatures_of_an_analytic_law(tmp_path):
    with pytest.raises(ValueError, match="temperatures"):
        plot_flow_curves(LAWS["hansel-spittel"][0], str(tmp_path / "x.png"))
    assert not (tmp_path / "x.png").exists()


def test_hansel_spittel_negative_m4_at_the_floor_warns():
    """m4 < 0 makes e^(m4/ε̄) vanish at the strain floor: a warning with the factor and a floor
    that cures it; the cured floor, and a mild m4, say nothing."""
    with pytest.warns(UserWarning, match="nearly without strength.*raise strain_floor"):
        HanselSpittel(A=1500.0, m1=-0.0025, m2=0.1, m3=0.14, m4=-0.05)
    floor = 0.05 / 2.3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        law = HanselSpittel(A=1500.0, m1=-0.0025, m2=0.1, m3=0.14, m4=-0.05,
                               strain_floor=floor)
        HanselSpittel(A=1500.0, m1=-0.0025, m2=0.1, m3=0.14, m4=-1e-4)
    ratio = law.sigma0(0.0, 1.0, 1000.0) / law.sigma0(0.1, 1.0, 1000.0)
    assert 0.1 < ratio < 1.0
