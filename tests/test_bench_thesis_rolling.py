"""Smoke test of the flat-rolling comparison harness (benchmarks/bench_thesis_rolling.py): a few
increments of a subset of the variants at a reduced size give a complete, finite table and the
acceptance checks are evaluated on it (their outcome is the benchmark's, not checked here)."""

import math
import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "benchmarks"))
import bench_thesis_rolling as bench  # noqa: E402


def test_size_parameters():
    p = bench.size_parameters(1.0)
    assert (p["h_x"], p["ny"], p["nz"], p["dt"]) == (3.0, 8, 4, 0.75e-3)
    p = bench.size_parameters(0.5)
    assert (p["h_x"], p["ny"], p["nz"], p["dt"]) == (6.0, 4, 2, 1.5e-3)
    with pytest.raises(ValueError, match="size"):
        bench.size_parameters(0.0)
    with pytest.raises(ValueError, match="unknown variant"):
        bench.run_variant("coarse-bezier-implicit", 0.4)


NAMES = ["analytic-implicit", "analytic-explicit", "fine-flat-implicit", "coarse-flat-implicit",
         "coarse-nagata-implicit"]


@pytest.fixture(scope="module")
def smoke_rows():
    """Two increments of five variants at size 0.4."""
    return bench.summarize([bench.run_variant(n, 0.4, max_increments=2) for n in NAMES])


@pytest.mark.serial   # a dozen short runs; the process's MPI path is tested in test_flat_rolling
@pytest.mark.slow
def test_table_complete_and_finite(smoke_rows):
    names, rows = NAMES, smoke_rows
    assert [r["variant"] for r in rows] == names
    for r in rows:
        assert set(bench.COLUMNS) <= set(r)
        for k in bench.COLUMNS[2:]:
            assert math.isfinite(r[k]) and r[k] >= 0, (r["variant"], k, r[k])
        assert r["increments"] == 2 and r["contact_nodes"] > 0 and r["eps_end"] > 0
    assert rows[0]["force_ratio"] == 1.0
    acc = bench.acceptance(rows)
    assert set(acc) >= {"nagata closer, force_per_width, implicit",
                        "nagata closer, eps_end, implicit",
                        "penetration implicit <= explicit/3, analytic"}
    text = bench.table(rows) + bench.table(rows, markdown=True) + bench.acceptance_text(acc)
    assert "nan" not in text and all(n in text for n in names)
    assert "0.91" in bench.thesis_text()


@pytest.mark.serial
@pytest.mark.xfail(strict=True, reason="issue acceptance 'implicit penetration <= 1/3 of "
                   "explicit' contradicted by measurement on a convex roll: here (2 increments, "
                   "size 0.4) implicit 1.0e-3 mm, explicit 4.4e-4 mm (bite-in); at steady state "
                   "the explicit (tangent-plane) nodes end outside the roll by about "
                   "(v_t dt)^2/2R (gap 4.0e-3 mm vs 3.75e-3 predicted) and do not penetrate, "
                   "the implicit error is the penalty's own penetration (2.3e-3 mm); "
                   "benchmarks/README.md")
@pytest.mark.slow
def test_implicit_penetration_below_a_third_of_explicit(smoke_rows):
    acc = bench.acceptance(smoke_rows)
    a = acc["penetration implicit <= explicit/3, analytic"]
    print(f"analytic roll: implicit {a['implicit']:.3e} mm, explicit {a['explicit']:.3e} mm")
    assert a["ok"]
