import numpy as np
import torch
import trimesh

from neurender import mitsuba_setup
from neurender.metaball import Scene
from neurender.simplification import implicit, render, views


def test_ray_marched_ball_matches_mitsuba_sphere(mitsuba):
    """Two independent renderers, one camera and shading model: a single metaball is a
    sphere, so the ray marcher and Mitsuba's render of a fine icosphere must agree."""
    mi, _ = mitsuba
    centre = np.array([0.3, 0.2, -0.1])
    ball = Scene(
        torch.tensor(centre[None]),
        torch.tensor([0.8], dtype=torch.float64),
        torch.full((1, 3), 0.5, dtype=torch.float64),
    )
    test_views = views.sample_views(2, 0, "test", 8.0, 30.0, (-180, 180), (-60, 60), 6.0, 50.0)
    sphere = trimesh.creation.icosphere(5, radius=0.8)
    shape = mitsuba_setup.mesh(mi, sphere.vertices + centre, sphere.faces, render.material(mi, 0.5))
    ours = np.stack([implicit.render_implicit(ball, v, 32, 4, 40.0) for v in test_views])
    theirs = render.render_views(mi, shape, test_views, 32, 256, 40.0, seed=0)
    assert np.abs(ours[..., 3] - theirs[..., 3]).mean() < 0.01
    assert np.abs(ours[..., :3].sum() / theirs[..., :3].sum() - 1) < 0.02
    assert np.abs(ours[..., :3] - theirs[..., :3]).mean() < 0.02 * theirs[..., :3].mean() + 1e-3


def test_baked_normal_map_follows_mitsubas_tangent_convention(mitsuba, baked_plane):
    """Bake a constant world normal onto a plane with an arbitrary (xatlas) UV layout; Mitsuba's
    normal-mapped BSDF must then shade with that normal (a swapped or flipped tangent would
    shade with another one)."""
    mi, dr = mitsuba
    w = np.array([0.45, -0.3, 0.84])
    w /= np.linalg.norm(w)
    low, normal_map = baked_plane(64, w, subdivisions=2)
    shape = mitsuba_setup.mesh(
        mi, low.atlas_positions(), low.uv_faces, render.material(mi, 1.0, normal_map), low.uvs
    )
    scene = mi.load_dict({"type": "scene", "shape": shape})
    si = scene.ray_intersect(mi.Ray3f(o=mi.Point3f(0.13, -0.21, 3.0), d=mi.Vector3f(0, 0, -1)))
    bsdf = si.bsdf()
    for azimuth in np.linspace(0, 2 * np.pi, 6, endpoint=False):
        wo = np.array([0.3 * np.cos(azimuth), 0.3 * np.sin(azimuth), 0.954])
        value = np.array(
            bsdf.eval(mi.BSDFContext(), si, si.to_local(mi.Vector3f(*map(float, wo))))
        ).ravel()[0]
        # Mitsuba softens normal-mapped shading near grazing angles by < 1 % here.
        assert np.isclose(value * np.pi, max(np.dot(w, wo), 0), rtol=0.02, atol=1e-3)
