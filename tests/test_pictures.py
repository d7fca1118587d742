"""The matplotlib helpers of ``fxcontact.io`` (``figure``, ``plot_pressure_profile``) and the
demos' pictures drawn with them, on made-up data (the runs' pictures: test_hertz.py)."""

import os

import numpy as np
import pytest

import fxcontact as fx
from fxcontact.processes import hertz_cylinder, hertz_sphere, hyperelastic


def test_figure_saves_and_closes(tmp_path):
    import matplotlib.pyplot as plt

    path = tmp_path / "a.png"
    with fx.figure(str(path), ncols=2) as (fig, axes):
        assert len(axes) == 2
        axes[0].plot([0, 1], [0, 1])
    assert path.stat().st_size > 1000
    assert not plt.get_fignums()
    bad = tmp_path / "b.png"
    with pytest.raises(RuntimeError, match="inside"):
        with fx.figure(str(bad)) as (fig, ax):
            raise RuntimeError("inside")
    assert not bad.exists() and not plt.get_fignums()


def test_pressure_profile_against_hertz(tmp_path):
    """The ellipse p/p0 = √(1 − s²/a²) over [0, a]; the nodes within 2a only, scaled by a and
    p0; the extent's line at s/a."""
    a, p0 = 2.0, 100.0
    s = np.array([0.0, 1.0, 3.0, 4.5])
    p = np.array([100.0, 80.0, 0.0, 0.0])
    with fx.figure(str(tmp_path / "p.png")) as (fig, ax):
        fx.plot_pressure_profile(ax, a, p0, [(s, p, dict(marker="s", label="FE"))],
                                 variable="x", extent=(1.8, "FE extent"))
        hertz, nodes, extent = ax.get_lines()
        x, y = hertz.get_data()
        assert x[0] == 0.0 and x[-1] == pytest.approx(1.0)
        assert np.allclose(y, np.sqrt(1.0 - x ** 2))
        assert np.allclose(nodes.get_xdata(), [0.0, 0.5, 1.5])
        assert np.allclose(nodes.get_ydata(), [1.0, 0.8, 0.0])
        assert nodes.get_marker() == "s" and nodes.get_label() == "FE"
        assert np.allclose(extent.get_xdata(), 0.9)
        assert ax.get_xlabel() == "$x/a$"


def test_demo_pictures_on_made_up_results(tmp_path):
    """The Hertz runs' and the hyperelastic run's pictures (fxcontact.processes) from results of
    the right shape."""
    r = np.linspace(0.0, 0.3, 20)
    one = dict(r=r, x=r, p=np.maximum(0.0, 1.0 - (r / 0.2) ** 2), p_max=1.0, force=10.0,
               hertz_contact_radius=0.2, hertz_half_width=0.2, hertz_p_max=1.0,
               contact_radius=0.19, contact_half_width=0.19, indentation=0.01,
               hertz_force=10.0, tool_facet_size=0.05)
    paths = [hertz_sphere.plot_tools({"analytic": one, "flat": one}, ("analytic", "flat"),
                                     str(tmp_path / "tools.png")),
             hertz_sphere.plot_profile(one, str(tmp_path / "sphere.png")),
             hertz_cylinder.plot_profile(one, str(tmp_path / "cyl.png"))]
    rows = [dict(indentation=0.1 * k, force=k ** 1.5) for k in range(1, 4)]
    paths.append(hyperelastic.plot_force(
        [dict(rows=rows, driver=d, newton=5, wall_time=1.0) for d in ("newton", "snes")],
        str(tmp_path / "force.png")))
    for path in paths:
        assert os.path.getsize(path) > 10_000, path
