"""cvkit: a course kit for Image Processing and Computer Vision.

Reference implementations of every algorithm in the course notes (one module per topic:
``cvkit.filters``, ``cvkit.noise``, ...), a registry of algorithms and providers
(:mod:`cvkit.registry`), and the grading engine behind the course notebooks
(:mod:`cvkit.grading`).

>>> import cvkit
>>> cvkit.registry.get("filters.gaussian").section
'3.9.1'
"""
from __future__ import annotations

import importlib

from . import registry
from .registry import algorithm, student, use

__version__ = "0.1.0"
__all__ = ["registry", "algorithm", "student", "use", "__version__"]


def __getattr__(name):  # lazy access to cvkit.filters, cvkit.grading, cvkit.data, ...
    try:
        return importlib.import_module(f"{__name__}.{name}")
    except ModuleNotFoundError as exc:
        if exc.name == f"{__name__}.{name}":
            raise AttributeError(f"module 'cvkit' has no attribute {name!r}") from None
        raise
