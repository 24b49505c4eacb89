"""casekit's border mistakes: the wrong border rule, whatever way the case passes ``border``."""
from __future__ import annotations

import inspect

import numpy as np
import pytest

from cvkit.filters import gaussian, pad
from cvkit.grading.casekit import (
    SWAPPED_REFLECT_HINT,
    border_mistakes,
    border_zero,
    reflect_swapped,
    with_border,
)

IMAGE = np.random.default_rng(3).random((5, 6))


@pytest.mark.parametrize("call", [((IMAGE, 1.3), {}), ((IMAGE, 1.3, "reflect"), {}),
                                  ((IMAGE, 1.3), {"border": "reflect101"}), ((IMAGE,), {"sigma": 1.3, "border": "replicate"})])
def test_with_border_replaces_the_border_however_it_is_passed(call):
    args, kwargs = call
    given = kwargs.get("border", args[2] if len(args) > 2 else "reflect101")
    sigma = kwargs.get("sigma", args[1] if len(args) > 1 else None)
    swapped = {"reflect": "reflect101", "reflect101": "reflect"}.get(given, given)
    np.testing.assert_array_equal(with_border(gaussian, "zero")(*args, **kwargs), gaussian(IMAGE, sigma, "zero"))
    np.testing.assert_array_equal(with_border(gaussian, lambda b: swapped)(*args, **kwargs),
                                  gaussian(IMAGE, sigma, swapped))


def test_with_border_keeps_the_signature_and_leaves_the_input_alone():
    before = IMAGE.copy()
    wrong = with_border(pad, "zero")
    assert inspect.signature(wrong) == inspect.signature(pad)
    out = wrong(IMAGE, 1, border="replicate")
    assert out[0, 0] == 0.0 and np.array_equal(IMAGE, before)


def test_with_border_names_the_callers_mistake():
    with pytest.raises(TypeError, match="no argument 'border'"):
        with_border(lambda image: image, "zero")
    with pytest.raises(TypeError, match="function must be callable"):
        with_border("gaussian", "zero")


def test_the_border_mistakes_in_order_with_their_hints():
    zero, swapped = border_mistakes(pad, "read through border")
    assert (zero.name, zero.hint) == ("border ignored (always zero)", "read through border")
    assert (swapped.name, swapped.hint) == ("reflect and reflect101 swapped", SWAPPED_REFLECT_HINT)
    np.testing.assert_array_equal(swapped.function(IMAGE, 2, "reflect"), pad(IMAGE, 2, "reflect101"))
    np.testing.assert_array_equal(zero.function(IMAGE, 2), pad(IMAGE, 2, "zero"))
    assert border_zero(pad, "h").name == zero.name and reflect_swapped(pad).hint == swapped.hint
