"""Reading and writing a run: the VTK series and CSV history writers and the pictures
(:mod:`~fxcontact.io.series`), a simulation's outputs (:mod:`~fxcontact.io.outputs`), and the
partition-independent keys of vertices and dofs that checkpoints (:mod:`fxcontact.checkpoint`)
and remeshed restores use (:mod:`~fxcontact.io.keys`), the flow curves of a flow-stress law
(:mod:`~fxcontact.io.flow_curves`)."""

from fxcontact.io.flow_curves import plot_flow_curves
from fxcontact.io.series import (HistoryWriter, SeriesWriter, figure, gather_mesh_data,
                                 plot_pressure_profile, read_pvd, render_png, write_pvd)

__all__ = ["HistoryWriter", "SeriesWriter", "figure", "gather_mesh_data", "plot_flow_curves",
           "plot_pressure_profile", "read_pvd", "render_png", "write_pvd"]
