"""Reading and writing a run: the VTK series and CSV history writers and the pictures
(:mod:`~fxcontact.io.series`, :mod:`~fxcontact.io.pictures`), a simulation's outputs
(:mod:`~fxcontact.io.outputs`), its checkpoints and their partition-independent keys
(:mod:`~fxcontact.io.checkpoint`)."""

from fxcontact.io.series import (HistoryWriter, SeriesWriter, figure, gather_mesh_data,
                                 plot_pressure_profile, read_pvd, render_png, write_pvd)

__all__ = ["HistoryWriter", "SeriesWriter", "figure", "gather_mesh_data", "plot_pressure_profile",
           "read_pvd", "render_png", "write_pvd"]
