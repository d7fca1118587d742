"""The short ring-rolling run with cones shared by test_ring_cones.py and
test_ring_checkpoint.py (computed once per process): two increments of the quick (coarse)
case 1 with the axial cone rolls and a checkpoint at each increment, and the run resumed from
its checkpoint of increment 1."""

import atexit
import functools
import os
import shutil
from dataclasses import replace

from mpi4py import MPI

from fxcontact.checkpoint import list_checkpoints
from fxcontact.processes import RingRollingCase, ring_rolling
from helpers import shared_tmpdir

NI = RingRollingCase().quick().increments_per_rev
#: two increments of the quick (coarse) case 1 with the cones
CONES = replace(RingRollingCase.case1(cones=True).quick(), revolutions=2.0 / NI)


def _cleanup(d):
    if MPI.COMM_WORLD.rank == 0:
        shutil.rmtree(d, ignore_errors=True)


@functools.lru_cache(maxsize=None)
def cone_runs():
    """(uninterrupted run, resumed run, checkpoint paths, directory) on COMM_WORLD."""
    d = shared_tmpdir("fxc_ring_cones_")
    atexit.register(_cleanup, d)
    full = ring_rolling.run(CONES, output_dir=os.path.join(d, "full"), pictures=False,
                            checkpoint_every=1)
    ck = list_checkpoints(os.path.join(d, "full", "checkpoints"))
    resumed = ring_rolling.run(CONES, output_dir=os.path.join(d, "resumed"), pictures=False,
                               resume=ck[0])
    return full, resumed, ck, d
