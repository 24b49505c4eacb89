"""`pip install cvkit` is lean: NumPy and SciPy only, SciPy imported when a function needs it,
and the course's tools (nbgrader, JupyterLab, matplotlib, ...) never imported by the library."""
from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

from cvkit import registry

ROOT = Path(__file__).resolve().parent.parent
COURSE_TOOLS = ("scipy", "matplotlib", "nbgrader", "jupyter", "jupyterlab", "tqdm", "skimage", "sklearn",
                "nbconvert", "nbformat", "nh3", "copydetect", "dask")


def test_the_install_requires_numpy_and_scipy_only():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = sorted(d.split(">")[0].split("=")[0].split("[")[0].strip() for d in project["dependencies"])
    assert names == ["numpy", "scipy"]
    extras = project["optional-dependencies"]
    assert {"data", "learn", "course", "test"} <= set(extras)
    assert any(d.startswith("nbgrader") for d in extras["course"])


def test_importing_the_library_imports_no_scipy_and_no_course_tool():
    modules = ["cvkit"] + [f"cvkit.{topic}" for topic in registry.topic_modules()] + ["cvkit.data"]
    code = (f"import sys\nimport {', '.join(modules)}\n"
            f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({COURSE_TOOLS!r})))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]", f"imported at import time: {done.stdout.strip()}"


def test_a_function_that_needs_scipy_imports_it_when_called():
    """A 31×31 kernel on a 200×200 image takes correlate's FFT route, which imports scipy.fft
    then; its result equals the direct sum on a window."""
    code = ("import sys, numpy as np\nfrom cvkit import filters\n"
            "before = 'scipy.fft' in sys.modules\n"
            "rng = np.random.default_rng(0); image, kernel = rng.random((200, 200)), rng.random((31, 31))\n"
            "out = filters.correlate(image, kernel, border='zero')\n"
            "direct = float((image[85:116, 85:116] * kernel).sum())\n"
            "print(before, 'scipy.fft' in sys.modules, abs(out[100, 100] - direct) < 1e-9)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False", "True", "True"]
