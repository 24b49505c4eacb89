"""Docstring text shared by several reference functions, written once.

A docstring names a shared piece as ``%(name)s`` on a line of its own, indented like the
text around it; :func:`filler` returns a decorator that replaces every such placeholder with
the text of ``name`` (the approach of SciPy's ``ndimage`` docstrings). The decorator changes
only ``__doc__``: the function itself, its name, signature and registration stay the same.

A piece's first line carries no indentation; its other lines carry the indentation of the
docstring they end up in (eight spaces for an entry under ``Parameters`` of a module-level
function), so that the filled docstring reads exactly as if written out in full.

>>> fill = filler({"x": "x : float\\n        The value."})
>>> @fill
... def f(x):
...     '''Identity.
...
...     Parameters
...     ----------
...     %(x)s
...     '''
...     return x
>>> print(f.__doc__.splitlines()[4:6])
['    x : float', '        The value.']
"""
from __future__ import annotations

import re
from typing import Callable, Mapping, TypeVar

__all__ = ["filler", "IMAGE_BORDER"]

_F = TypeVar("_F", bound=Callable[..., object])
_PLACEHOLDER = re.compile(r"%\((\w+)\)s")

#: the entries of the filters' and edge detectors' ``image`` and ``border`` parameters
IMAGE_BORDER = {
    "image": ("image : (H, W) or (H, W, 3) array_like\n"
              "        Grayscale or colour image, any real dtype, finite values (colour: per channel)."),
    "border": ('border : {"reflect101", "reflect", "replicate", "zero"}\n'
               "        How pixels outside the image are made up (§3.7)."),
}


def filler(pieces: Mapping[str, str]) -> Callable[[_F], _F]:
    """A decorator that fills the ``%(name)s`` placeholders of a docstring from ``pieces``.

    Parameters
    ----------
    pieces : mapping of str to str
        The shared text of each placeholder name.

    Returns
    -------
    callable
        ``fill(function) -> function``: the same object, its ``__doc__`` filled in. A
        placeholder whose name ``pieces`` lacks is a ``KeyError`` naming it (at import, where
        the decorator runs).
    """
    def substitute(match: re.Match[str]) -> str:
        name = match.group(1)
        if name not in pieces:
            raise KeyError(f"docstring placeholder %({name})s has no text; known: {sorted(pieces)}")
        return pieces[name]

    def fill(function: _F) -> _F:
        if function.__doc__:
            function.__doc__ = _PLACEHOLDER.sub(substitute, function.__doc__)
        return function

    return fill
