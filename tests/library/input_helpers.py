"""What the library's bad-input tests share: hypothesis settings for quick property runs, and
the assertion that a call is refused with a message naming the argument."""
from __future__ import annotations

import pytest
from hypothesis import HealthCheck, settings

#: a quick property run: the inputs are small, a run must not wait on hypothesis' own deadlines
FAST = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def raises_naming(exc, name, fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` raises ``exc`` with a message that names ``name`` (the argument)."""
    with pytest.raises(exc) as info:
        fn(*args, **kwargs)
    assert name in str(info.value), f"message {str(info.value)!r} does not name {name!r}"
