"""The nbgrader course pipeline behind ``cvkit course ...`` and ``cvkit demo`` (see :mod:`.course`)."""
from .course import *  # noqa: F401,F403
from .course import _reported_mistakes  # noqa: F401  (tests/test_feedback_words.py)
