"""What runs inside the grading sandbox, next to the student's code.

This package uses only NumPy and the standard library, and it is the *only* part of cvkit
that exists inside the sandbox where hidden cases are decided (it is bound there as the
top-level package ``cvkit_runtime``; cvkit's reference implementations are not):

- :mod:`.worker` — the sandbox's main program: runs the answer cells, then each case the
  trusted side sends, one at a time, and streams back plain data;
- :mod:`.guard` — copies of the inputs, a friendly time limit, captured output, and a watch
  on calls into functions an exercise forbids (e.g. ``numpy.pad`` for the padding exercise);
- :mod:`.wire` — the JSON encoding of values crossing the boundary (never pickle);
- :mod:`.adapters`, :mod:`.problems` — how checks of classes and of optimisers call the
  candidate (:attr:`cvkit.grading.Check.call`).

Nothing here is trusted by the grader: the student's code can change any of it at run time.
That is why only *data* leaves the sandbox and every verdict is taken outside.
"""
