"""Offscreen pyvista rendering in a clean process (see :func:`fxcontact.io.render_png`).

Usage: ``python path/to/fxcontact/_render.py spec.json`` (by its path: ``-m`` would import the
package, and with it dolfinx). Never imports dolfinx.
"""

import json
import os
import sys


def main(spec_path: str) -> int:
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista

    with open(spec_path) as fh:
        spec = json.load(fh)
    pyvista.OFF_SCREEN = True
    body = pyvista.read(spec["body"])
    pl = pyvista.Plotter(off_screen=True, window_size=spec["window_size"])
    if spec["scalar"]:
        pl.add_mesh(body, scalars=spec["scalar"], show_edges=spec["show_edges"], cmap="viridis",
                    clim=spec["clim"], scalar_bar_args={"title": spec["scalar"]})
    else:
        pl.add_mesh(body, show_edges=spec["show_edges"], color="lightsteelblue")
    for f in spec["extras"]:
        pl.add_mesh(pyvista.read(f), color="lightgrey", opacity=0.45)
    if spec["title"]:
        pl.add_text(spec["title"], font_size=12)
    cam = spec["camera"]
    if cam == "iso":
        pl.view_isometric()
    else:
        getattr(pl, f"view_{cam}")()
    pl.screenshot(spec["png"])
    pl.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
