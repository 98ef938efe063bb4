import numpy as np
import pytest
import trimesh

from neurender import mitsuba_setup
from neurender.simplification import bake, mesh_ops, optimise, render, views


def test_tonemap_is_srgb_of_log1p(mitsuba):
    mi, dr = mitsuba
    x = np.array([0.0, 1e-3, 0.5, 3.0, 100.0])
    y = np.log1p(x)
    expected = np.where(y <= 0.0031308, 12.92 * y, 1.055 * y ** (1 / 2.4) - 0.055)
    assert np.allclose(np.array(optimise.tonemap(dr, mi.Float(x))), expected, rtol=2e-4)


def test_laplacian_decay_keeps_the_papers_schedule_shape():
    # prod_t 10^(-k t) over the first fraction f of the run depends on k (f steps)^2 / 2.
    for steps in (100, 1000):
        k = optimise.laplacian_decay(steps)
        assert np.isclose(k * (0.2 * steps) ** 2, optimise.PAPER_DECAY_K * 2000**2)


def test_the_config_takes_every_value_from_the_stage_and_names_a_missing_key():
    """No optimiser setting has a default of its own: the schema's are the only ones."""
    cfg = dict(steps=3, batch=2, spp=4, resolution=16, lr_positions=1e-3, lr_textures=1e-2)
    cfg |= dict(lr_final_fraction=0.05, laplacian_scale=0.5, laplacian_min_fraction=0.1)
    cfg |= dict(intensity=70.0, seed=1, camera_distance=6.5)  # a key it does not read
    settings = optimise.OptimiseConfig.from_stage(cfg, optimise_albedo=True)
    assert (settings.width, settings.batch, settings.laplacian_scale) == (16, 2, 0.5)
    assert settings.optimise_albedo and settings.optimise_positions
    del cfg["laplacian_min_fraction"], cfg["batch"]
    with pytest.raises(KeyError, match=r"\['batch', 'laplacian_min_fraction'\]"):
        optimise.OptimiseConfig.from_stage(cfg)


def test_references_need_one_image_per_view():
    one = views.sample_views(1, 0, "train", 4.0, 40.0, (-30, 30), (-30, 30), 3.0, 60.0)
    with pytest.raises(ValueError, match="2 reference images for 1 views"):
        optimise.References(one, np.zeros((2, 4, 4, 4), np.float32))


def test_latent_mesh_normals_and_laplacian(mitsuba):
    mi, dr = mitsuba
    sphere = trimesh.creation.icosphere(3)
    vertices = np.asarray(sphere.vertices, dtype=np.float32)
    low = mesh_ops.LowPolyMesh(
        sphere.vertices,
        sphere.faces,
        np.arange(len(sphere.vertices)),
        np.zeros((len(sphere.vertices), 2)),
        sphere.faces,
    )
    latent = optimise.LatentMesh(mi, dr, low)
    p = latent.points(mi.Float(np.ravel(vertices)))
    n = np.array(latent.normals(p))
    radial = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", n.T if n.shape[0] == 3 else n, radial) > 0.99).all()
    # The uniform Laplacian of a vertex on a sphere points inwards (towards its ring's centre).
    delta = np.array(latent.laplacian(p))
    delta = delta.T if delta.shape[0] == 3 else delta
    assert (np.einsum("ij,ij->i", delta, radial) > 0).all()
    pairs, valence = optimise.neighbour_pairs(sphere.faces, len(sphere.vertices))
    assert valence.sum() == len(pairs) == 2 * len(sphere.edges_unique)


def test_optimisation_recovers_a_normal_map(mitsuba, baked_plane):
    """References rendered with a constant tilted normal map; starting from a flat map the
    optimised map must move most of the way to the truth (texels the cameras see)."""
    mi, dr = mitsuba
    low, truth = baked_plane(16, [0.4, 0.2, 0.89], subdivisions=1)
    train_views = views.sample_views(6, 0, "train", 4.0, 40.0, (-30, 30), (-30, 30), 3.0, 60.0)
    shape = mitsuba_setup.mesh(
        mi, low.atlas_positions(), low.uv_faces, render.material(mi, 0.8, truth), low.uvs
    )
    references = render.render_views(mi, shape, train_views, 24, 64, 20.0, seed=0)
    flat = np.broadcast_to([0.5, 0.5, 1.0], truth.shape).copy()
    cfg = optimise.OptimiseConfig(
        steps=30,
        batch=2,
        spp=4,
        width=24,
        lr_positions=0.0,
        lr_textures=0.05,
        lr_final_fraction=0.2,
        laplacian_scale=0.25,
        laplacian_min_fraction=0.02,
        intensity=20.0,
        seed=0,
        optimise_positions=False,
    )
    positions, normal_map, albedo, loss = optimise.optimise(
        mi,
        dr,
        optimise.Start(low, flat, 0.8),
        optimise.References(train_views, references),
        cfg,
    )
    assert albedo is None and np.allclose(positions, low.positions)
    covered = np.zeros(truth.shape[:2], bool)
    s = bake.rasterise_uvs(low.uvs, low.uv_faces, 16)
    covered[s.rows, s.cols] = True
    before = np.abs(flat - truth)[covered].mean()
    after = np.abs(normal_map - truth)[covered].mean()
    assert after < 0.5 * before
    image_loss = loss[loss["metric"] == "image_l1"]["value"].to_numpy()
    # 4-spp noise puts a floor under the image loss.
    assert image_loss[-10:].mean() < 0.8 * image_loss[:10].mean()
