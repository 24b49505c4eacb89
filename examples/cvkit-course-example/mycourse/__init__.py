"""mycourse: exercises for the cvkit course kit.

cvkit imports this package through its entry point (group ``cvkit.algorithms``); importing it
imports every exercise module next to this file, and each registers its reference
implementation and check with ``@cvkit.algorithm("mycourse.<name>", ...)``.
"""
import importlib
import pkgutil

for _module in pkgutil.iter_modules(__path__):
    if not _module.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_module.name}")
