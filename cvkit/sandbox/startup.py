"""Start-up cost of the grading processes.

Every grading process (the instructor's ``cvkit course`` process, each parallel worker, and the
sandboxed run of each notebook) imports ``nbformat``, which imports ``jsonschema``. When the
optional package ``rfc3987_syntax`` is installed (JupyterLab's ``jupyter-events`` pulls it in),
``jsonschema`` compiles its 38 IRI grammars with ``lark`` at import: 1.4 s of CPU per process,
about a sixth of the time a short chapter's notebook takes to grade. The grammars only check
the ``iri``/``iri-reference`` string formats, which the notebook schema never uses, so grading
processes skip them. Library users who ``import cvkit`` are not affected.
"""
from __future__ import annotations

import sys


def skip_unused_schema_grammars() -> None:
    """Make ``jsonschema`` skip the IRI grammars in this process (see the module docstring).
    Does nothing once ``jsonschema`` is imported, or when ``rfc3987_syntax`` already is."""
    if "jsonschema" not in sys.modules:
        modules: dict = sys.modules  # None in sys.modules: importing the name raises ImportError
        modules.setdefault("rfc3987_syntax", None)
