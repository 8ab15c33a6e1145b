"""How messages show values (``core.validation.value_text``): numbers as Python writes them,
whatever NumPy type they come in, never a NumPy repr, on one line."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import core
from core.validation import value_text

SHOWN = [
    (-1.0, "-1.0"),
    (np.float64(-1.0), "-1.0"),
    (np.float32(-1.0), "-1.0"),
    (np.float32(0.1), "0.1"),                  # its shortest float32 form, not 0.100000001...
    (np.float32(np.pi), "3.1415927"),
    (np.float16(0.1), "0.1"),
    (np.float64(0.1), "0.1"),
    (np.float64(1e-300), "1e-300"),
    (np.float32(3e38), "3e+38"),
    (np.float32(3.4028235e38), "3.4028235e+38"),   # float32's largest, without a warning
    (np.float64("nan"), "nan"),
    (np.float32("-inf"), "-inf"),
    (np.int64(-5), "-5"),
    (np.int32(7), "7"),
    (np.uint8(255), "255"),
    (np.bool_(True), "True"),
    (np.bool_(False), "False"),
    (True, "True"),
    (3, "3"),
    (np.array(2.5), "2.5"),                    # 0-d arrays
    (np.array(np.float32(0.1)), "0.1"),
    (np.array(4, np.int64), "4"),
    (np.array(False), "False"),
    (np.array([1.0, np.nan, -2.0]), "[1.0, nan, -2.0]"),
    (np.array([1, 2, 3], np.int64), "[1, 2, 3]"),
    (np.array([0.1, 0.2], np.float32), "[0.1, 0.2]"),
    (np.array([[1.0, 0.0], [0.0, 1.0]]), "[[1.0, 0.0], [0.0, 1.0]]"),
    (np.arange(10.0), "[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, ... (10 items)]"),
    ((np.float64(1.0), np.float32(0.5), np.int64(2)), "(1.0, 0.5, 2)"),
    ((np.float64(1.0),), "(1.0,)"),
    ([np.bool_(True), None], "[True, None]"),
    ("Sphere", "'Sphere'"),
    (np.str_("Sphere"), "'Sphere'"),
    (np.complex128(1 + 2j), "(1+2j)"),
]


@pytest.mark.parametrize("value, text", SHOWN, ids=[f"{type(v).__name__}-{t}" for v, t in SHOWN])
def test_values_read_as_python_writes_them(value, text):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert value_text(value) == text


def test_no_text_is_a_numpy_repr_or_spans_lines():
    for value, _ in SHOWN + [(np.zeros((40, 40)), None), (np.ones((3, 3, 3)), None)]:
        text = value_text(value)
        assert "np." not in text and "array(" not in text and "dtype" not in text, text
        assert "\n" not in text


def test_other_objects_show_their_repr_on_one_line_cut_short():
    class Long:
        def __repr__(self):
            return "a\nb " + "x" * 500

    text = value_text(Long())
    assert text.startswith("a b x") and text.endswith("...") and len(text) <= 120


@pytest.mark.parametrize("make, message", [
    (lambda: core.Sphere((0, 0, 0), np.array(-1.0), name="ball"),
     "sphere 'ball'.radius must be > 0, got -1.0"),
    (lambda: core.Material(reflection=np.array(np.float32(1.5))),
     "material.reflection must be in [0, 1], got 1.5"),
    (lambda: core.SurfaceMaterial(diffuse=(np.float64(0.5), np.array(np.nan), 0.5)),
     "surface material.diffuse[1] must be finite, got nan"),
    (lambda: core.SphereSet(np.zeros((2, 3)), np.ones(2), np.array([0, 3]),
                            (core.Material(),), name="Points"),
     "sphere set 'Points': material_indices[1] must be in [0, 1) (materials), got 3"),
    (lambda: core.SurfaceMaterial(holdout_object=np.array(1)),
     "surface material.holdout_object must be True or False, got 1"),
])
def test_the_cores_messages_show_numbers_as_numbers(make, message):
    """(0-d arrays, whose repr is NumPy's under any version, show that the message goes
    through value_text; radii[17] is the message NumPy 2 made unreadable.)"""
    with pytest.raises(core.SceneError) as raised:
        make()
    assert str(raised.value) == message


def test_warnings_show_numbers_as_numbers():
    """The warning NumPy 2 made read "radii[17] is np.float64(-1.0)"."""
    spheres = core.SphereSet(np.zeros((20, 3)), np.r_[np.ones(17), -1.0, np.ones(2)],
                             np.zeros(20, np.int64), (core.Material(),), name="Points")
    assert spheres.warnings == ("sphere set 'Points': 1 of 20 spheres draw nothing, as in "
                                "Cycles (radii[17] is -1.0)",)
    light = core.SpotLight((0, 0, 0), np.zeros(3, np.float32), power=np.float32(5.0), name="Spot")
    assert light.warnings == ("light 'Spot': direction is [0.0, 0.0, 0.0] (the light is scaled "
                              "to 0): it emits nothing",)
