"""Projection throughput of the analytic tools: numba kernels versus the numpy reference twins.

Usage::

    python benchmarks/bench_projection_analytic.py [--n 1000000] [--repeat 3]

For every tool the JIT is warmed up first, then ``tool.project(x)`` is timed (best of
``--repeat``) with and without the Hessian, for both backends, in the same run. The last rows
time a *moving* tool (translation + rotation), where the base class maps points to the
reference frame and rotates the results back.
"""

import argparse

import numpy as np
from _common import best_time

from fxcontact.tools.analytic import Cone, Cylinder, Plane, Sphere


def tools(backend):
    return [
        ("plane", Plane((0.1, 0.0, 0.2), (0.3, 0.2, 1.0), backend=backend)),
        ("sphere", Sphere((0.0, 0.1, 0.0), 1.0, backend=backend)),
        ("spherical cavity", Sphere((0.0, 0.1, 0.0), 1.0, inside=True, backend=backend)),
        ("cylinder", Cylinder((0.0, 0.0, 0.0), (0.2, 0.1, 1.0), 0.8, backend=backend)),
        ("bore", Cylinder((0.0, 0.0, 0.0), (0.2, 0.1, 1.0), 0.8, inside=True, backend=backend)),
        ("cone", Cone((0.0, 0.0, -1.0), (0.1, 0.0, 1.0), 0.5, backend=backend)),
        ("conical bore", Cone((0.0, 0.0, -1.0), (0.1, 0.0, 1.0), 0.5, inside=True,
                              backend=backend)),
    ]


def moving_tools(backend):
    return [
        ("cylinder, moving", Cylinder((0.0, 0.0, 0.0), (0.2, 0.1, 1.0), 0.8,
                                      velocity=(1.0, 0.0, 0.0), angular_velocity=3.0,
                                      backend=backend)),
        ("cone, moving", Cone((0.0, 0.0, -1.0), (0.1, 0.0, 1.0), 0.5, velocity=(0.0, 0.0, 1.0),
                              angular_velocity=3.0, backend=backend)),
    ]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=10**6, help="number of points (default 1e6)")
    parser.add_argument("--repeat", type=int, default=3, help="timings per case, best kept")
    args = parser.parse_args()

    x = np.random.default_rng(0).uniform(-2.0, 2.0, (args.n, 3))
    rows = []
    for builder, t in ((tools, 0.0), (moving_tools, 0.1)):
        for (name, tb), (_, tn) in zip(builder("numba"), builder("numpy")):
            tb.project(x[:10], t)  # JIT warm-up (and cache load)
            tn.project(x[:10], t)
            rate = {}
            for hess in (True, False):
                for label, tool in (("numba", tb), ("numpy", tn)):
                    dt = best_time(lambda: tool.project(x, t, hessian=hess), args.repeat)
                    rate[label, hess] = args.n / dt
            rows.append((name, rate))

    print(f"analytic tool projection, N = {args.n:,} points, best of {args.repeat} "
          f"[million points/s]")
    head = (f"{'tool':<18} | {'numba +H':>9} {'numpy +H':>9} {'ratio':>6} | "
            f"{'numba':>9} {'numpy':>9} {'ratio':>6}")
    print(head)
    print("-" * len(head))
    for name, r in rows:
        cells = []
        for hess in (True, False):
            a, b = r["numba", hess], r["numpy", hess]
            cells.append(f"{a / 1e6:9.1f} {b / 1e6:9.1f} {a / b:6.1f}")
        print(f"{name:<18} | {cells[0]} | {cells[1]}")
    print("+H: with the gap Hessian; ratio = numba / numpy throughput")


if __name__ == "__main__":
    main()
