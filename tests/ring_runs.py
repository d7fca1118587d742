"""The short ring-rolling run with cones shared by test_ring_cones.py and
test_ring_checkpoint.py (computed once per process): two increments of the quick (coarse)
case 1 with the axial cone rolls and a checkpoint at each increment, and the run resumed from
its checkpoint of increment 1."""

import atexit
import functools
import os
import shutil
import sys

from mpi4py import MPI

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "demos"))
import demo_ring_rolling as demo  # noqa: E402

from fxcontact.checkpoint import list_checkpoints  # noqa: E402
from helpers import shared_tmpdir  # noqa: E402

NI = demo.QUICK["increments_per_rev"]
#: two increments of the quick (coarse) case 1 with the cones
CONES = {**demo.QUICK, "case": 1, "cones": True, "revolutions": 2.0 / NI, "pictures": False}


def _cleanup(d):
    if MPI.COMM_WORLD.rank == 0:
        shutil.rmtree(d, ignore_errors=True)


@functools.lru_cache(maxsize=None)
def cone_runs():
    """(uninterrupted run, resumed run, checkpoint paths, directory) on COMM_WORLD."""
    d = shared_tmpdir("fxc_ring_cones_")
    atexit.register(_cleanup, d)
    full = demo.run(**CONES, output_dir=os.path.join(d, "full"), checkpoint_every=1)
    ck = list_checkpoints(os.path.join(d, "full", "checkpoints"))
    resumed = demo.run(**CONES, output_dir=os.path.join(d, "resumed"), resume=ck[0])
    return full, resumed, ck, d
