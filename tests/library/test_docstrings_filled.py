"""Shared docstring text (cvkit._docstrings): filled in, and nothing else about a function changes."""
from __future__ import annotations

import importlib
import inspect
import re

import pytest

import cvkit.registry as registry
from cvkit._docstrings import IMAGE_BORDER, filler

PLACEHOLDER = re.compile(r"%\(\w+\)s")


def _module_level(image, border="reflect101", *, k: int = 2) -> int:
    """Doc.

    Parameters
    ----------
    %(image)s
    %(border)s
    """
    return k


def test_filler_fills_the_placeholders_and_keeps_the_function():
    f = _module_level
    before = inspect.signature(f)
    same = filler(IMAGE_BORDER)(f)
    assert same is f
    assert inspect.signature(f) == before
    assert f.__name__ == "_module_level" and f(None) == 2
    doc = inspect.getdoc(f)
    assert "    image : (H, W) or (H, W, 3) array_like\n" in f.__doc__
    assert "image : (H, W) or (H, W, 3) array_like\n    Grayscale or colour image" in doc
    assert 'border : {"reflect101", "reflect", "replicate", "zero"}\n    How pixels outside' in doc
    assert not PLACEHOLDER.search(doc)


def test_filler_leaves_other_percent_signs_and_missing_docstrings_alone():
    def g():
        """50 % of %d pixels; %(x)s."""

    def h():
        pass

    filler({"x": "X"})(g)
    filler({"x": "X"})(h)
    assert g.__doc__ == "50 % of %d pixels; X."
    assert h.__doc__ is None


def test_an_unknown_placeholder_is_named():
    def g():
        """%(nope)s"""

    with pytest.raises(KeyError, match="nope"):
        filler(IMAGE_BORDER)(g)


def test_no_reference_docstring_keeps_a_placeholder():
    for topic in registry.topic_modules():
        importlib.import_module(f"cvkit.{topic}")
    left = [a.id for a in registry.algorithms() if PLACEHOLDER.search(a.reference.__doc__ or "")]
    assert not left, left
    # the shared text really is in the docstrings that use it
    from cvkit.edges import laplacian, sobel
    from cvkit.filters import gaussian

    for function in (sobel, laplacian, gaussian):
        assert IMAGE_BORDER["border"] in function.__doc__
