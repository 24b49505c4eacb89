"""nbgrader configuration of the cvkit course in this checkout.

The chapter notebooks in ``lectures/`` are the nbgrader *source*: ``lectures/chNN_topic/``
is the assignment ``chNN_topic``. Generated folders (release/, submitted/, autograded/,
feedback/) and the gradebook live next to this file (or in ``$CVKIT_COURSE_ROOT``) and are
never committed. The settings themselves are cvkit's (:mod:`cvkit.course.nbgrader_settings`,
which lists the environment overrides); a course folder of its own (``cvkit new course``)
calls the same function with its own folders.
"""
from pathlib import Path

from cvkit.course.nbgrader_settings import configure

HERE = Path(__file__).resolve().parent
configure(get_config(), HERE, source=HERE.parent / "lectures", project=HERE.parent)  # noqa: F821
