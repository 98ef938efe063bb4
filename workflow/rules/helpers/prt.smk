# Helpers of workflow/rules/prt.smk: the names and input files its rules use (their params:
# neurender.prt.rule_keys).

from neurender.jobs import input_name
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


wildcard_constraints:
    object="[A-Za-z0-9_]+",
    probe="[A-Za-z0-9_]+",
    split="|".join(PRT_SPLITS),
    material="|".join(PRT_MATERIALS),
    variant="|".join(VARIANTS),


def prt_variant_files(kind, objects=None, materials=PRT_MATERIALS):
    """The ``kind`` file (``pt``, ``onnx``, ``int8.onnx`` or ``loss.csv``) of every trained
    variant and material, per object (``objects``; ``None``: the rule's own ``{object}``
    wildcard), as named inputs (``input_name(kind, [object,] variant, material)``)."""
    suffix = f".{kind}" if kind in ("pt", "onnx") else f"_{kind}"
    pairs = [(v, m) for v in PRT_VARIANTS for m in materials]
    if objects is None:
        base = "results/prt/{object}/variants"
        return {input_name(kind, v, m): f"{base}/{v}_{m}{suffix}" for v, m in pairs}
    return {
        input_name(kind, o, v, m): f"results/prt/{o}/variants/{v}_{m}{suffix}"
        for o in objects
        for v, m in pairs
    }


def prt_momoprt_files(materials=PRT_MATERIALS):
    """MoMoPRT's fits of the rule's own ``{object}``, as named inputs
    (``input_name("momoprt", material)``)."""
    return {
        input_name("momoprt", m): f"results/prt/{{object}}/momoprt_{m}.npz"
        for m in materials
    }


def prt_shipped_files(wildcards):
    """The shipped variant's checkpoint, ONNX file and int8 ONNX file of one object and
    material."""
    base = f"results/prt/{wildcards.object}/variants/{PRT_SHIPPED}_{wildcards.material}"
    return {
        "checkpoint": f"{base}.pt",
        "onnx": f"{base}.onnx",
        "int8": f"{base}_int8.onnx",
    }


def prt_shipped_summary_files():
    """Of every object, as named inputs: the shipped graphs (``input_name("shipped",
    object, material)``, their int8 forms ``"shipped_int8"``) and the frames of each split
    (``input_name("frames", object, split)``)."""
    files = {}
    for o in PRT_OBJECTS:
        for m in PRT_MATERIALS:
            files[input_name("shipped", o, m)] = f"results/prt/{o}/deepprt_{m}.onnx"
            files[input_name("shipped_int8", o, m)] = (
                f"results/prt/{o}/deepprt_{m}_int8.onnx"
            )
        for split in PRT_SPLITS:
            files[input_name("frames", o, split)] = f"results/prt/{o}/{split}"
    return files


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
