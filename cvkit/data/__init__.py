"""Images and data sets for the notebooks, made by code or shipped with installed packages.

Every loader returns float64 arrays in [0, 1] (grayscale ``(H, W)`` or RGB ``(H, W, 3)``)
unless it says otherwise; nothing is downloaded. The sample pictures and the stereo pair are
scikit-image's (the optional extra ``pip install "cvkit[data]"``), the digits scikit-learn's
(``pip install "cvkit[learn]"``): without them those loaders raise an ``ImportError`` that says
so, and everything made by code works without either. The loaders live in private submodules by
theme (``_images``: scikit-image's bundled pictures and noise helpers; further modules add
stereo pairs, chessboard views, digits, synthetic shapes); every public name of every
submodule (its ``__all__``) is available here.

>>> from cvkit import data
>>> data.camera().shape
(512, 512)
"""
from __future__ import annotations

import importlib
import pkgutil

__all__: list[str] = []

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if not _info.name.startswith("_"):
        continue
    _module = importlib.import_module(f"{__name__}.{_info.name}")
    for _name in getattr(_module, "__all__", ()):
        if _name in globals() and globals()[_name] is not getattr(_module, _name):
            raise ImportError(f"cvkit.data: {_name!r} is defined by two data modules")
        globals()[_name] = getattr(_module, _name)
        __all__.append(_name)
del _info, _module
