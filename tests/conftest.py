import pytest

from neurender.mitsuba_setup import import_mitsuba


@pytest.fixture(scope="session")
def mitsuba():
    """``(mi, dr)`` on the CPU (the llvm variant CI has)."""
    return import_mitsuba("cpu")


@pytest.fixture(scope="session")
def tensorboard_steps():
    """``folder -> {tag: [steps]}`` of every scalar and image in a TensorBoard folder, read
    back with TensorBoard's own reader."""
    from tensorboard.backend.event_processing import event_accumulator as reader

    def read(folder) -> dict[str, list[int]]:
        acc = reader.EventAccumulator(str(folder), size_guidance={"scalars": 0, "images": 0})
        acc.Reload()
        steps = {t: [e.step for e in acc.Scalars(t)] for t in acc.Tags()["scalars"]}
        return steps | {t: [e.step for e in acc.Images(t)] for t in acc.Tags()["images"]}

    return read
