"""Static 3D figures of meshes, drawn off-screen by PyVista (VTK), written as PNG.

A figure is a grid of :class:`Panel` s, one mesh each, all seen by one camera (linked
views) from :data:`VIEW` (a direction towards the camera; world space right-handed, y up),
lit by VTK's default light kit. Panels of a grid mesh (a geometry image, ``(n, n, 3)``)
draw its grid lines, not the triangles' diagonals. PyVista is imported when a figure is
drawn (headless through EGL or OSMesa, whichever the VTK wheel finds; no display needed).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from neurender import io

#: Direction towards the camera: in front (+z), a little right and above.
VIEW = (0.35, 0.45, 1.0)
EDGE_COLOUR = "#202020"
SURFACE_COLOUR = "#d8d8d8"


@dataclasses.dataclass
class Panel:
    """One mesh of a figure.

    Attributes:
        vertices: ``(V, 3)`` positions, or ``(n, n, 3)`` for a grid mesh.
        faces: ``(F, 3)`` triangles; None for a grid mesh.
        title: text in the panel's top left corner.
        scalars: ``(V,)`` (or ``(n, n)``) values coloured by ``cmap`` over ``clim``, or None.
        colours: ``(V, 3)`` RGB in [0, 1] per vertex, or None (grey unless ``scalars``).
        edges: draw the mesh's edges (a grid mesh: its grid lines).
        clim: the colour range of ``scalars``; scalar_title: its colour bar's title (a bar
            is drawn only where given).
    """

    vertices: np.ndarray
    faces: np.ndarray | None = None
    title: str = ""
    scalars: np.ndarray | None = None
    colours: np.ndarray | None = None
    edges: bool = False
    clim: tuple[float, float] | None = None
    scalar_title: str | None = None
    cmap: str = "viridis"


def _pyvista():
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def _mesh(pv, panel: Panel):
    v = np.asarray(panel.vertices, dtype=np.float64)
    if panel.faces is None:
        if v.ndim != 3 or v.shape[-1] != 3:
            raise ValueError(f"panel {panel.title!r}: a grid mesh needs (n, n, 3), got {v.shape}")
        mesh = pv.StructuredGrid(v[..., 0], v[..., 1], v[..., 2])
        values = None if panel.scalars is None else np.asarray(panel.scalars).ravel(order="F")
        colours = None if panel.colours is None else panel.colours.reshape(-1, 3, order="F")
    else:
        faces = np.asarray(panel.faces, dtype=np.int64)
        cells = np.column_stack([np.full(len(faces), 3), faces]).ravel()
        mesh = pv.PolyData(v, cells)
        values, colours = panel.scalars, panel.colours
    if values is not None:
        mesh.point_data["scalars"] = np.asarray(values, dtype=np.float64)
    if colours is not None:
        mesh.point_data["rgb"] = io.to_uint8(np.asarray(colours))
    return mesh


def render_panels(
    panels: list[Panel],
    path: str | Path,
    shape: tuple[int, int],
    window_size: tuple[int, int],
    groups: list | None = None,
    view: tuple[float, float, float] = VIEW,
) -> None:
    """Draw ``panels`` into a ``shape`` (rows, columns) grid of subplots (``groups``:
    PyVista's merged cells, e.g. ``[(slice(0, 2), slice(0, 2))]``; the panels fill the
    remaining cells row by row) of ``window_size`` pixels and write the PNG atomically.
    One camera, shared by every panel, frames all the meshes."""
    pv = _pyvista()
    plotter = pv.Plotter(
        off_screen=True, shape=shape, groups=groups, window_size=list(window_size), border=False
    )
    cells = _cells(shape, groups)
    if len(panels) > len(cells):
        raise ValueError(f"{len(panels)} panels for a {shape} layout with {len(cells)} cells")
    plotter.set_background("white")
    bounds = []
    for panel, (row, col) in zip(panels, cells, strict=False):
        plotter.subplot(row, col)
        mesh = _mesh(pv, panel)
        bounds.append(np.reshape(mesh.bounds, (3, 2)))
        style = {"show_edges": panel.edges, "edge_color": EDGE_COLOUR, "line_width": 1}
        if panel.colours is not None:
            plotter.add_mesh(mesh, scalars="rgb", rgb=True, smooth_shading=True, **style)
        elif panel.scalars is not None:
            bar = {
                "title": panel.scalar_title,
                "vertical": False,
                "n_labels": 3,
                "position_x": 0.15,
                "position_y": 0.03,
                "width": 0.7,
                "height": 0.1,
                "title_font_size": 12,
                "label_font_size": 11,
                "color": "black",
            }
            plotter.add_mesh(
                mesh,
                scalars="scalars",
                cmap=panel.cmap,
                clim=panel.clim,
                smooth_shading=True,
                show_scalar_bar=panel.scalar_title is not None,
                scalar_bar_args=bar,
                **style,
            )
        else:
            plotter.add_mesh(mesh, color=SURFACE_COLOUR, smooth_shading=True, **style)
        plotter.add_text(panel.title, position="upper_left", font_size=9, color="black")
    plotter.link_views()
    plotter.subplot(*cells[0])
    plotter.view_vector(view, viewup=(0.0, 1.0, 0.0))
    box = np.stack(bounds)
    plotter.reset_camera(bounds=np.column_stack([box[:, :, 0].min(0), box[:, :, 1].max(0)]).ravel())
    with io.atomic_path(path) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()


def _cells(shape: tuple[int, int], groups: list | None) -> list[tuple[int, int]]:
    """The subplot cells in drawing order: each group's first cell (groups are pairs of
    slices), then the cells no group covers, row by row."""
    covered = np.zeros(shape, bool)
    firsts = []
    for rows, cols in groups or []:
        covered[rows, cols] = True
        firsts.append((rows.start or 0, cols.start or 0))
    free = [(int(r), int(c)) for r, c in np.argwhere(~covered)]
    return firsts + free
