import numpy as np
import trimesh

from neurender import mitsuba_setup
from neurender.simplification import mesh_ops, render, terminator, views


def _hit(mi, shape, origin, direction):
    scene = mi.load_dict({"type": "scene", "shape": shape})
    return scene.ray_intersect(
        mi.Ray3f(o=mi.Point3f(*map(float, origin)), d=mi.Vector3f(*map(float, direction)))
    )


def _view(origin, light, fov):
    """A camera at ``origin`` looking at the world origin, the point light at ``light``."""
    return views.View(origin, (0.0, 0.0, 0.0), fov, light=light, azimuth=0.0, elevation=0.0)


def test_offset_lifts_a_point_onto_the_smooth_surface(mitsuba):
    """One triangle cut from the unit sphere, normals = positions: the shift of a hit equals
    the formula evaluated independently in numpy and moves it towards the sphere."""
    mi, dr = mitsuba
    v = np.array([[1.0, 0.2, 0.1], [0.1, 1.0, 0.3], [0.2, 0.1, 1.0]])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    faces = np.array([[0, 1, 2]])
    shape = mitsuba_setup.mesh(mi, v, faces, render.material(mi, 0.5), normals=v)
    b = np.array([0.5, 0.3, 0.2])
    p = b @ v
    si = _hit(mi, shape, 3 * p, -p / np.linalg.norm(p))
    shift = np.array(terminator.terminator_offset(mi, dr, si)).ravel()
    hit = np.array(si.p).ravel()
    expected = -sum(b[i] * min(np.dot(hit - v[i], v[i]), 0.0) * v[i] for i in range(3))
    assert np.allclose(shift, expected, atol=1e-5)
    assert np.linalg.norm(shift) > 1e-3
    assert abs(np.linalg.norm(hit + shift) - 1) < abs(np.linalg.norm(hit) - 1)


def test_offset_is_zero_for_flat_normals_and_misses(mitsuba):
    mi, dr = mitsuba
    v = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    up = np.tile([0.0, 0.0, 1.0], (3, 1))
    shape = mitsuba_setup.mesh(mi, v, np.array([[0, 1, 2]]), render.material(mi, 0.5), normals=up)
    assert np.allclose(
        np.array(terminator.terminator_offset(mi, dr, _hit(mi, shape, [0.1, 0, 2], [0, 0, -1]))), 0
    )
    assert np.allclose(
        np.array(terminator.terminator_offset(mi, dr, _hit(mi, shape, [5, 5, 2], [0, 0, -1]))), 0
    )


def test_terminator_integrator_renders_a_coarse_sphere_closer_to_a_smooth_one(mitsuba):
    """An 80-triangle sphere with smooth normals lit from the side: Mitsuba's ``direct``
    darkens jagged bands near the terminator that a fine sphere does not have; the fixed
    integrator must come closer to the fine sphere where both cover the pixel."""
    mi, dr = mitsuba
    coarse, fine = (trimesh.creation.icosphere(k) for k in (1, 5))
    view = _view((0.0, 0.0, 4.0), (4.0, 0.0, 1.5), 40.0)
    white = render.material(mi, 0.8)

    def image(mesh, integrator):
        shape = mitsuba_setup.mesh(mi, mesh.vertices, mesh.faces, white)
        scene = mi.load_dict(render.scene_dict(mi, shape, view, 64, 16, 20.0, integrator))
        return np.array(mi.render(scene, seed=0))

    reference = image(fine, None)
    plain, fixed = (image(coarse, it) for it in (None, terminator.integrator(mi, dr)))
    lit = (reference[..., 3] > 0.99) & (plain[..., 3] > 0.99) & (reference[..., 0] > 0.02)
    dark_plain = (plain[..., 0] < 0.5 * reference[..., 0])[lit].sum()
    dark_fixed = (fixed[..., 0] < 0.5 * reference[..., 0])[lit].sum()
    assert dark_plain > 20
    assert dark_fixed < 0.25 * dark_plain
    err = [np.abs(x - reference)[lit, :3].mean() for x in (plain, fixed)]
    assert err[1] < err[0]
    # Alpha is coverage, as Mitsuba's own direct integrator writes it.
    assert fixed[..., 3].min() == 0 and fixed[..., 3].max() == 1
    assert np.abs(fixed[..., 3] - plain[..., 3]).mean() < 0.01


def test_gradients_match_direct_projective_where_nothing_shifts(mitsuba, baked_plane):
    """On a plane (every vertex normal = the face normal) the fix shifts nothing, so the
    vertex gradients must be direct_projective's, silhouettes included."""
    mi, dr = mitsuba
    fixed = terminator.integrator(mi, dr, spp=4)
    low, _ = baked_plane(8, [0, 0, 1], subdivisions=1)
    view = _view((0.5, 0.3, 3.0), (1.0, 1.0, 2.0), 50.0)
    grads = []
    for integrator in ({**fixed, "type": "direct_projective"}, fixed):
        shape = render.atlas_shape(mi, low, render.material(mi, 0.7))
        scene = mi.load_dict(
            render.scene_dict(
                mi, shape, view, 24, 4, 10.0, integrator, alpha=False, sample_border=True
            )
        )
        params = mi.traverse(scene)
        key = "shape.vertex_positions"
        dr.enable_grad(params[key])
        params.update()
        image = mi.render(scene, params, seed=3, spp=4)
        dr.backward(dr.mean(image, axis=None))
        grads.append(np.array(dr.grad(params[key])))
    assert np.abs(grads[0]).max() > 0
    assert np.allclose(grads[0], grads[1], rtol=1e-4, atol=1e-7)


def test_atlas_normals_are_welded_across_uv_seams():
    """Atlas copies of one welded vertex get one normal (the welded mesh's); the atlas
    mesh's own normals differ at seams, which split the shading there."""
    sphere = trimesh.creation.icosphere(2)
    low = mesh_ops.uv_atlas(np.asarray(sphere.vertices), np.asarray(sphere.faces), 64)
    normals = low.atlas_normals()
    radial = low.atlas_positions() / np.linalg.norm(low.atlas_positions(), axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", normals, radial) > 0.99).all()
    seams = np.bincount(low.vmap)[low.vmap] > 1
    assert seams.any()
    own = trimesh.Trimesh(low.atlas_positions(), low.uv_faces, process=False).vertex_normals
    assert np.einsum("ij,ij->i", own[seams], radial[seams]).min() < 0.99
