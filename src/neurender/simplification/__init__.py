"""Appearance-driven simplification (Hasselgren et al. 2021): a low-polygon mesh with
textures, optimised through Mitsuba 3 to match a reference renderer's images.

This module names what the workflow's rules refer to; it imports nothing heavy, so the
Snakefile can read it when it builds the DAG.
"""

#: The salt of the method's random streams (:func:`neurender.rng.stable_seed`): the
#: package's name before 0.2, kept so that the renamed package draws the same numbers.
SEED_SALT = "simplify"

#: The built-in use cases (paper 4.1: the detailed head; 4.5: a metaball implicit surface).
CASES = ("head", "metaballs")

#: The simplified meshes every case's evaluation renders (:mod:`neurender.simplification.evaluate`):
#: a QEM decimation, the decimation with baked textures, and ours (optimised).
VARIANTS = ("qem", "baked", "ours")

#: Ours as shipped, read back from its exported files and rendered by the evaluation beside
#: :data:`VARIANTS`: variant name -> the key of its file in :data:`EXPORT_FILES`.
EXPORTED = {"ours_glb": "glb", "ours_obj": "obj"}

#: The files of a case the evaluation reads, by the key it reads them under.
CASE_FILES = {
    "lowpoly": "lowpoly.npz",
    "baked_normal": "baked_normal.png",
    "baked_albedo": "baked_albedo.png",
    "test_views": "views_test.csv",
    "test_images": "reference_test.exr",
    "mesh": "optimised.npz",
    "normal": "optimised_normal.png",
    "albedo": "optimised_albedo.png",
    "loss": "loss.csv",
}

#: The exported files of a case (written by its deploy job, read back and rendered by the
#: evaluation): the GLB and the OBJ, each with the files it names beside it.
EXPORT_FILES = {
    "glb": "optimised.glb",
    "obj": "optimised.obj",
    "mtl": "optimised.mtl",
    "texture": "optimised_texture.png",
    "normal_texture": "optimised_texture_normal.png",
}
