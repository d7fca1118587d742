"""The README's Python example runs (at a smaller size) and gives the classical answer.

The example is taken from README.md as it is, only its element size, duration and output
directory are changed, so an example that no longer matches the API fails here.
"""

import re
from pathlib import Path

import numpy as np
import pytest

from helpers import shared_tmpdir

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_example() -> str:
    """The first ``python`` code block of the section "Use it from your own FEniCSx code"."""
    text = README.read_text(encoding="utf-8")
    section = text.split("## Use it from your own FEniCSx code", 1)[1]
    m = re.search(r"```python\n(.*?)```", section, re.S)
    assert m, "no python code block in the README section"
    return m.group(1)


def _shrink(code: str, outdir: str) -> str:
    for old, new in (("h=2.0", "h=4.0"), ("t_end=0.9, dt=0.06", "t_end=0.3, dt=0.1"),
                     ('output_dir="out"', f"output_dir={outdir!r}")):
        assert code.count(old) == 1, f"README example changed: {old!r} not found once"
        code = code.replace(old, new)
    return code


def test_readme_example_uses_one_import():
    code = readme_example()
    imports = [ln for ln in code.splitlines() if re.match(r"\s*(import|from)\s", ln)]
    assert imports == ["from mpi4py import MPI", "import fxcontact as fx"]


def test_readme_example_runs():
    outdir = shared_tmpdir("fxc-readme-")
    ns = {"__name__": "readme_example"}
    exec(compile(_shrink(readme_example(), outdir), "README.md", "exec"), ns)
    hist, sim = ns["history"], ns["sim"]
    assert len(hist) == 3
    # frictionless flat dies: homogeneous upsetting, force = sigma_0 * V / h with the Norton-Hoff
    # flow stress sigma_0 = sqrt(3) K (sqrt(3) eps_dot)^m at eps_dot = v / h (THEORY §14.1). The
    # last increment is solved on the configuration at its start, t = 0.2 (updated Lagrangian).
    K, m, v = 50.0, 0.15, 5.0
    h = 15.0 - v * 0.2
    sigma0 = np.sqrt(3.0) * K * (np.sqrt(3.0) * v / h) ** m
    force = hist[-1]["die_force_z"]
    expected = sigma0 * sim.volume() / h  # quarter billet, mesh volume (faceted lateral face)
    assert force == pytest.approx(expected, rel=0.02)
    assert 0.0 <= hist[-1]["contact_penetration_true"] < 1e-2 * 4.0


def process_examples():
    """The python code blocks of the section "Forming processes": drawing, extrusion,
    upsetting."""
    text = README.read_text(encoding="utf-8")
    section = text.split("## Forming processes", 1)[1].split("\n## ", 1)[0]
    return [b for b in re.findall(r"```python\n(.*?)```", section, re.S)
            if "DrawingCase" in b or "ExtrusionCase" in b or "UpsettingCase" in b]


def test_process_examples_are_short_and_use_the_process_library():
    blocks = process_examples()
    assert len(blocks) == 3
    for code in blocks:
        assert len(code.strip().splitlines()) <= 40
        assert code.startswith("from fxcontact.processes import ")


@pytest.mark.parametrize("which,shrink", [
    (0, (("R0=10.0, R1=7.5", "R0=5.0, R1=3.75"), ("h=1.9", "h=1.5"), ("land=2.0", "land=1.0"),
         ("t_end=0.1", "t_end=0.01, length=18.0, facet=1.0, fillet=1.0, relief_length=0.5"))),
    (1, (("R0=10.0, R1=6.0, length=30.0", "R0=5.0, R1=3.5, length=14.0"), ("h=1.5", "h=1.0"),
         ("t_end=1.0", "t_end=0.05, land=0.5, fillet=0.5, entry_fillet=0.5, relief_length=0.5"))),
    (2, (("R0=10.0", "R0=5.0"), ("h=1.5", "h=1.25"), ("reduction=0.7", "reduction=0.1"))),
], ids=["drawing", "extrusion", "upsetting"])
def test_process_example_runs(which, shrink):
    """Each example as written, at the tests' reduced size (the replaced strings must be there
    once), with its outputs in a temporary directory."""
    code = process_examples()[which]
    outdir = shared_tmpdir("fxc-readme-process-")
    for old, new in shrink + (('output_dir="results/', f'output_dir="{outdir}/'),):
        assert code.count(old) == 1, f"README example changed: {old!r} not found once"
        code = code.replace(old, new)
    ns = {"__name__": "readme_process_example"}
    exec(compile(code, "README.md", "exec"), ns)
    res = ns["res"]
    assert res.status == "completed", res.message
    if which < 2:
        assert res.increments == round(ns["case"].t_end / ns["case"].dt)
    else:   # a start-up increment, then increments of dt × h/H0
        assert res.reduction == pytest.approx(0.1) and res.out_of_band == []
    assert abs(res.power_balance_penalty) < 1e-6
