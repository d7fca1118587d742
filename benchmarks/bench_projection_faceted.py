"""Projection throughput of faceted tools: flat (Forge) versus Nagata, numba versus numpy twin.

Tools are structured cylinders R = 5 mm (lateral surface) of about 10^2, 10^4 and 10^5 triangles;
the query points lie within ±0.05 mm of the surface, as contact nodes do. Each line gives the
construction time, the projection throughput (numba kernels, after warm-up; gap, normal and
gap Hessian) for near points and for far points (5 mm away), the throughput of the plain
numpy/Python reference twin on a subset of the same points, and the Nagata/flat cost ratio.

Usage::

    python benchmarks/bench_projection_faceted.py [--points 10000] [--sizes 100 10000 100000]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from _common import best_time

from fxcontact.tools.faceted import FacetedTool, flat_project_ref, nagata_project_ref


def cylinder_with(n_tri: int, radius: float = 5.0, length: float = 40.0):
    """Structured cylinder with ≈ n_tri triangles and facets of aspect ≈ 1."""
    from fxcontact.tools import surfaces as tm
    n_theta = max(6, int(round(math.sqrt(n_tri * math.pi * radius / length))))
    n_axial = max(1, int(round(n_tri / (2 * n_theta))))
    return tm.structured_cylinder(radius, length, n_theta, n_axial)


def points_near(n: int, rng, radius=5.0, length=40.0, band=0.05, offset=0.0):
    th = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(-0.45 * length, 0.45 * length, n)
    r = radius + offset + rng.uniform(-band, band, n)
    return np.stack([r * np.cos(th), r * np.sin(th), z], axis=1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 10_000, 100_000],
                    help="approximate numbers of triangles")
    ap.add_argument("--points", type=int, default=10_000, help="query points per projection")
    ap.add_argument("--twin-points", type=int, default=200,
                    help="points projected with the numpy reference twin")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)

    # warm-up (numba compilation or cache load)
    V, T = cylinder_with(100)
    for mode in ("flat", "nagata"):
        FacetedTool(V, T, mode=mode).project(points_near(10, rng))

    header = (f"{'triangles':>9} {'mode':>6} {'build s':>8} {'near pts/s':>11} "
              f"{'far pts/s':>10} {'twin pts/s':>10} {'numba/twin':>10} {'cand/pt':>7} "
              f"{'fallbacks':>9}")
    print(header)
    print("-" * len(header))
    ratios = []
    for size in args.sizes:
        V, T = cylinder_with(size)
        X = points_near(args.points, rng)
        Xfar = points_near(args.points, rng, offset=5.0)
        Xt = X[:args.twin_points]
        rate = {}
        for mode in ("flat", "nagata"):
            t0 = time.perf_counter()
            tool = FacetedTool(V, T, mode=mode)
            t_build = time.perf_counter() - t0
            tool.project(X[:10])
            t_near = best_time(lambda: tool.project(X), args.repeat)
            t_far = best_time(lambda: tool.project(Xfar), 1)
            ptr, idx = tool.candidates(Xt)
            twin = nagata_project_ref if mode == "nagata" else flat_project_ref
            t_twin = best_time(lambda: twin(tool, Xt, ptr, idx), 1)
            pr = tool.project(X)
            rate[mode] = args.points / t_near
            twin_rate = len(Xt) / t_twin
            print(f"{T.shape[0]:>9d} {mode:>6} {t_build:>8.3f} {rate[mode]:>11.3g} "
                  f"{args.points / t_far:>10.3g} {twin_rate:>10.3g} "
                  f"{rate[mode] / twin_rate:>10.0f} "
                  f"{np.diff(tool.candidates(X[:2000])[0]).mean():>7.2f} "
                  f"{int(pr.flag.sum()):>9d}")
        ratios.append((T.shape[0], rate["flat"] / rate["nagata"]))
    print()
    for n, r in ratios:
        print(f"Nagata/flat cost ratio, {n} triangles: {r:.2f} (goal <= 3)")


if __name__ == "__main__":
    main()
