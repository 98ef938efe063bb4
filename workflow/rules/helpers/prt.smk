# Helpers of workflow/rules/prt.smk: the names, config keys and input files its rules use.

from neurender.prt import (
    EXPERIMENTS,
    MATERIALS as PRT_MATERIALS,
    SPLITS as PRT_SPLITS,
    VARIANTS,
)

PRT_OBJECTS = list(config["prt"]["objects"])
#: The DeepPRT variants trained (each per object and material), and the one shipped.
PRT_VARIANTS = list(config["prt_model"]["variants"])
PRT_SHIPPED = config["prt_model"]["shipped"]
PRT_USER_SEQUENCES = config["prt"]["user_sequences"]
PRT_EXPERIMENTS = EXPERIMENTS if config["prt"]["experiments"] else ()
PRT_LIGHT = f"results/prt/probes/{config['prt']['light']}_sh.csv"
#: Training keys in one fixed order: snakemake compares a job's params as text, so a key
#: added for one variant leaves the other's params, and its networks, as they were.
PRT_TRAIN_KEYS = ("widths", "blocks", "epochs", "batch_size", "lr", "lr_schedule")
PRT_TRAIN_KEYS += ("residual_targets", "shadowing_batch_size", "shadowing_lr")
#: Keys that only one variant's training reads (the shadowing variant's architecture
#: constants live in neurender.prt.local_model.LocalConfig, not in the config).
PRT_VARIANT_KEYS = {
    "paper": ("batch_size", "lr", "residual_targets"),
    "shadowing": ("shadowing_batch_size", "shadowing_lr"),
}
PRT_TRANSFER_KEYS = ("n_bands", "direction_sets", "ray_offset")


wildcard_constraints:
    object="[A-Za-z0-9_]+",
    probe="[A-Za-z0-9_]+",
    split="|".join(PRT_SPLITS),
    material="|".join(PRT_MATERIALS),
    variant="|".join(VARIANTS),


def prt_params(prt_keys=(), model_keys=(), top=(), **extra):
    """A rule's keys of the ``prt`` and ``prt_model`` sections (:func:`section_keys`)."""
    return {
        **section_keys("prt", prt_keys, top),
        **section_keys("prt_model", model_keys),
        **extra,
    }


def prt_probe_params(wildcards):
    return prt_params(("probe_height", "n_bands"), probe=wildcards.probe)


def prt_geometry_image_params(wildcards):
    """Procedural objects read their vertex count; user meshes and animations do not."""
    keys = ("resolution",)
    if wildcards.object not in {**config["prt"]["user_meshes"], **PRT_USER_SEQUENCES}:
        keys += ("source_vertices",)
    return prt_params(keys, top=("seed",), object=wildcards.object)


def prt_sequence_params(wildcards):
    keys = ("frames", "experiment_points", "experiment_train_frames", "linear_range")
    keys += ("excluded_expression",)
    extra = {}
    if wildcards.object in PRT_USER_SEQUENCES:
        extra["test_fraction"] = PRT_USER_SEQUENCES[wildcards.object]["test_fraction"]
    return prt_params(keys, top=("seed",), object=wildcards.object, **extra)


def prt_transfer_params(wildcards):
    """Test frames get the clean reference's direction count (paper scale: >= 4x)."""
    key = "reference_directions" if wildcards.split == "test" else "directions"
    return prt_params(
        PRT_TRANSFER_KEYS,
        top=("seed",),
        object=wildcards.object,
        split=wildcards.split,
        directions=config["prt"][key],
    )


def prt_noise_floor_params(wildcards):
    keys = PRT_TRANSFER_KEYS + ("directions", "noise_floor_frames")
    return prt_params(keys, top=("seed",), object=wildcards.object)


def prt_figure_params(wildcards):
    return prt_params(("n_bands",), object=wildcards.object)


def prt_mesh_figure_params(wildcards):
    return prt_params(object=wildcards.object)


def prt_benchmark_params():
    keys = PRT_TRANSFER_KEYS + ("directions", "benchmark_paper_scale")
    return prt_params(keys, top=("seed",))


def prt_train_params(wildcards):
    """What a training job of one variant reads, so an edit of an evaluation key, or of a
    key only the other variant reads, never retrains."""
    others = {
        k for v, ks in PRT_VARIANT_KEYS.items() if v != wildcards.variant for k in ks
    }
    keys = tuple(k for k in PRT_TRAIN_KEYS if k not in others)
    return prt_params(
        ("n_bands",),
        keys,
        ("seed", "device"),
        material=wildcards.material,
        variant=wildcards.variant,
    )


def prt_deploy_params(wildcards):
    return prt_params(
        ("n_bands",),
        object=wildcards.object,
        variant=wildcards.variant,
        material=wildcards.material,
    )


def prt_ship_params(wildcards):
    return {"shipped": PRT_SHIPPED}


def prt_variant_files(kind, objects=None, materials=PRT_MATERIALS):
    """The ``kind`` file (``pt``, ``onnx``, ``int8.onnx`` or ``loss.csv``) of every trained
    variant, per object (``objects``; ``None``: the rule's own ``{object}`` wildcard) and
    material, in the order object, variant, material."""
    suffix = f".{kind}" if kind in ("pt", "onnx") else f"_{kind}"
    # The rule's own wildcard stays a wildcard: expand() turns {{object}} into {object}.
    where = {} if objects is None else {"object": objects}
    folder = "{{object}}" if objects is None else "{object}"
    path = f"results/prt/{folder}/variants/{{variant}}_{{material}}{suffix}"
    return expand(path, **where, variant=PRT_VARIANTS, material=materials)


def prt_shipped_files(wildcards):
    """The shipped variant's checkpoint, ONNX file and int8 ONNX file of one object and
    material."""
    base = f"results/prt/{wildcards.object}/variants/{PRT_SHIPPED}_{wildcards.material}"
    return {
        "checkpoint": f"{base}.pt",
        "onnx": f"{base}.onnx",
        "int8": f"{base}_int8.onnx",
    }


def prt_momoprt_params(wildcards):
    keys = ("pca_components", "ridges")
    return prt_params(("n_bands",), keys, material=wildcards.material)


def prt_evaluate_params(wildcards):
    """The scores' keys: the noise floor's ground truth (traced at both direction counts)
    and the renders."""
    keys = PRT_TRANSFER_KEYS + ("directions", "reference_directions")
    model = ("render_resolution", "glossy_exponent", "variants")
    return prt_params(keys, model, ("seed", "device"), object=wildcards.object)


def prt_equal_quality_params(wildcards):
    """The ray-traced estimates' keys (on the first noise_floor_frames test frames)."""
    keys = PRT_TRANSFER_KEYS + ("reference_directions", "noise_floor_frames")
    model = ("render_resolution", "equal_quality_directions", "variants")
    return prt_params(keys, model, ("seed", "device"), object=wildcards.object)


def prt_model_summary_params():
    return prt_params(
        ("resolution", "n_bands"),
        ("variants", "shipped"),
        objects=PRT_OBJECTS,
    )


def prt_unseen_params(wildcards):
    """The benchmark's sizes, its ground truth's keys and the scores' render keys."""
    keys = PRT_TRANSFER_KEYS + ("reference_directions",)
    model = ("render_resolution", "glossy_exponent", "variants")
    model += ("unseen_strengths", "unseen_frames")
    return prt_params(keys, model, ("seed", "device"), object=wildcards.object)


def prt_unseen_models(wildcards):
    """Every variant's network files (variant-major, then material: the job's order) and
    MoMoPRT's fits, of one object."""
    base = f"results/prt/{wildcards.object}"
    variants = config["prt_model"]["variants"]
    pairs = [(v, m) for v in variants for m in PRT_MATERIALS]
    return {
        "deepprt": [f"{base}/variants/{v}_{m}.pt" for v, m in pairs],
        "onnx": [f"{base}/variants/{v}_{m}.onnx" for v, m in pairs],
        "momoprt": [f"{base}/momoprt_{m}.npz" for m in PRT_MATERIALS],
    }


def prt_experiment_params(wildcards):
    """Fig. 6: the test-frame keys and the variants drawn (their files are its inputs)."""
    return {**prt_test_frame_params(wildcards), "variants": PRT_VARIANTS}


def prt_test_frame_params(wildcards):
    """The section 4.2.2 experiments and the relighting figure."""
    return prt_params(
        ("n_bands",), ("render_resolution",), ("device",), object=wildcards.object
    )


def prt_viewer_params(wildcards):
    """The report's view (the probes it turns are its input files)."""
    return prt_params(("n_bands",), top=("device",), object=wildcards.object)


def prt_probe_source(wildcards):
    """A user probe file is an input of its job, so editing it reruns the job."""
    path = config["prt"]["user_probes"].get(wildcards.probe)
    return {"source": as_input(path)} if path else {}


def prt_user_frames(name):
    """The frame files of a user animation (and of its separate test frames), inputs of
    the jobs that read them, so editing a frame reruns them."""
    entry = PRT_USER_SEQUENCES[name]
    inputs = {"frames": user_files(entry["frames"])}
    if entry["test_frames"]:
        inputs["test_frames"] = user_files(entry["test_frames"])
    return inputs


def prt_object_source(wildcards):
    """A user mesh file, or a user animation's frames, are inputs of the geometry-image
    job, so editing one reruns the job."""
    if wildcards.object in PRT_USER_SEQUENCES:
        return prt_user_frames(wildcards.object)
    path = config["prt"]["user_meshes"].get(wildcards.object)
    return {"source": as_input(path)} if path else {}


def prt_sequence_files(wildcards):
    """The geometry image (the section 4.2.2 experiments deform the head's), and a user
    animation's frames."""
    source = "head" if wildcards.object in EXPERIMENTS else wildcards.object
    inputs = {"gim": f"results/prt/{source}/geometry_image.npz"}
    if wildcards.object in PRT_USER_SEQUENCES:
        inputs.update(prt_user_frames(wildcards.object))
    return inputs


def prt_split_files(wildcards, splits=PRT_SPLITS):
    """Sequence file, frame folders and manifests of the given splits of one object."""
    base = f"results/prt/{wildcards.object}"
    inputs = {"seq": f"{base}/sequence.npz"}
    for split in splits:
        inputs[f"{split}_dir"] = f"{base}/{split}"
        inputs[f"{split}_manifest"] = f"{base}/{split}_manifest.csv"
    return inputs


def prt_training_files(wildcards):
    return prt_split_files(wildcards, ("train", "val"))


def prt_variant_training_files(wildcards):
    """A variant's training data; the shadowing variant's glossy network also reads the
    SH light (its analytic unshadowed part is the light's glossy polynomial)."""
    inputs = prt_training_files(wildcards)
    if wildcards.variant == "shadowing" and wildcards.material == "glossy":
        inputs["light"] = PRT_LIGHT
    return inputs


def prt_deploy_files(wildcards):
    """A trained network and the first frames of its training data (val: the export's
    check; train: the int8 graph's calibration)."""
    base = f"results/prt/{wildcards.object}/variants/{wildcards.variant}_{wildcards.material}"
    return {**prt_training_files(wildcards), "checkpoint": f"{base}.pt"}


def prt_evaluation_files(wildcards):
    return prt_split_files(wildcards, ("val", "test"))


def prt_test_files(wildcards):
    return prt_split_files(wildcards, ("test",))


def prt_train_priority(wildcards):
    """The object networks first, the shorter experiment networks after them and the
    seconds-long MoMoPRT fits (priority 0) in the gaps, so the two single-thread training
    jobs keep both cores busy until the last one ends."""
    return 1 if wildcards.object in EXPERIMENTS else 2
