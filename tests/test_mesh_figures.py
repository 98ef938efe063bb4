"""PyVista figures: every panel is drawn into a PNG of the asked size, off-screen."""

import numpy as np
import pytest
from PIL import Image

from neurender import mesh_figures
from neurender.geometry import grid_faces


def test_cells_put_each_group_first_then_the_free_cells_row_by_row():
    cells = mesh_figures._cells((2, 4), [(slice(0, 2), slice(0, 2))])
    assert cells == [(0, 0), (0, 2), (0, 3), (1, 2), (1, 3)]
    assert mesh_figures._cells((1, 3), None) == [(0, 0), (0, 1), (0, 2)]


def test_grid_and_triangle_panels_render_to_a_png_of_the_window_size(tmp_path):
    n = 12
    t = np.linspace(-1, 1, n)
    x, y = np.meshgrid(t, t)
    grid = np.stack([x, y, 0.3 * np.exp(-(x**2 + y**2))], -1)
    bumped = grid + [0.0, 0.0, 0.2]
    panels = [
        mesh_figures.Panel(grid, title="grid", edges=True),
        mesh_figures.Panel(bumped.reshape(-1, 3), grid_faces(n), title="triangles", edges=True),
        mesh_figures.Panel(bumped, title="scalars", scalars=x, clim=(-1.0, 1.0), scalar_title="x"),
    ]
    path = tmp_path / "meshes.png"
    mesh_figures.render_panels(panels, path, (1, 3), (480, 160))
    image = np.asarray(Image.open(path).convert("RGB"))
    assert image.shape == (160, 480, 3)
    for k in range(3):  # every panel draws something besides its white background
        cell = image[:, k * 160 : (k + 1) * 160]
        assert (cell.sum(-1) < 600).mean() > 0.02, k
    with pytest.raises(ValueError, match="3 panels for a"):
        mesh_figures.render_panels(panels, path, (1, 2), (320, 160))
    with pytest.raises(ValueError, match="needs \\(n, n, 3\\)"):
        mesh_figures.render_panels([mesh_figures.Panel(grid[0])], path, (1, 1), (80, 80))
