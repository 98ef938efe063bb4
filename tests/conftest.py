import pytest

from neurender.mitsuba_setup import import_mitsuba


@pytest.fixture(scope="session")
def mitsuba():
    """``(mi, dr)`` on the CPU (the llvm variant CI has)."""
    return import_mitsuba("cpu")
