"""Run student code safely: the operating-system sandbox and the processes that talk to it.

- :mod:`.isolation`: bubblewrap (namespaces, a read-only view of the Python environment, a
  private ``/tmp``, no network) and resource limits; the submission's files as they are read.
- :mod:`.session`: one sandboxed run of a notebook's answer cells on a list of calls (the
  trusted checks' cases), talking to the in-box worker of :mod:`cvkit.grading.runtime`.
- :mod:`.reference_server`: the building blocks an exercise may use, computed outside the box
  (which ids may be served is grading's rule, :mod:`cvkit.grading.served`).
- :mod:`.notebook_run`: a whole notebook executed in a fresh kernel inside the box, for the
  student's own outputs on the feedback page.
- :mod:`.startup`: start-up time saved in the processes started here.

Nothing here knows nbgrader, grade ids or courses (``tests/system/test_architecture.py``).
"""
