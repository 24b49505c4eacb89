"""What the sandbox printed reaches the reason a run gives, even when the box died at once.

:func:`cvkit.sandbox.session.require_worker` refuses to grade with "the sandbox said: …": the
words of bubblewrap or of the interpreter that could not start are the instructor's only clue.
A box that dies at once ends its run before the thread that reads its output has read it; the
output must be taken after that thread has read everything, not when the run stops.
"""
from __future__ import annotations

import time

from cvkit.grading.runtime import wire
from cvkit.sandbox import session


def test_a_box_that_dies_at_once_still_says_why(monkeypatch, grading_sandbox):
    reading = session._Session._read_output

    def late_reader(self):  # the output thread of a loaded machine, a little behind
        time.sleep(0.5)
        reading(self)

    monkeypatch.setattr(session._Session, "_read_output", late_reader)
    monkeypatch.setattr(session, "worker_interpreter", lambda: ("/nonexistent/python", [], []))
    result = session.run_calls(["def f(x):\n    return x"], [wire.BoxCall("f", args=(1,), time_limit=5.0)],
                               max_restarts=0)
    assert result.outcomes[0] is None or not result.outcomes[0].ok
    assert "/nonexistent/python" in result.output, result.output
