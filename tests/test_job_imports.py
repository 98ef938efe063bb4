"""A job loads only the libraries it uses: every method's job module (``jobs`` or
``data_jobs``, which a rule's shim in ``workflow/scripts/`` imports) imports without
torch, ONNX, matplotlib, Mitsuba or PyVista; its job functions import what they drive
when they run (torch alone takes 1 to 2 s)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "onnx", "onnxruntime", "matplotlib", "mitsuba", "pyvista")


def _job_modules() -> list[str]:
    """Every job module a shim imports its job from."""
    modules = set()
    for shim in (ROOT / "workflow" / "scripts").glob("*.py"):
        found = re.findall(r"^from (neurender[\w.]*) import (\w*jobs)$", shim.read_text(), re.M)
        modules |= {f"{package}.{name}" for package, name in found}
    return sorted(modules)


def test_every_shim_imports_a_job_module():
    assert {"neurender.prt.jobs", "neurender.prt.data_jobs", "neurender.ndr.jobs"} <= set(
        _job_modules()
    )


@pytest.mark.parametrize("module", _job_modules())
def test_a_job_module_imports_none_of_the_heavy_libraries(module):
    code = f"import sys, {module}; print([m for m in {HEAVY!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", f"{module} imports {out.stdout.strip()} at import time"
