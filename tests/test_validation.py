import numpy as np
import pytest

from faceanim.validation import as_array, as_index_array


def test_as_array_converts_and_keeps_values():
    out = as_array([[1, 2, 3]], "v", shape=("V", 3))
    assert out.dtype == np.float64 and out.flags.c_contiguous
    assert out.tolist() == [[1.0, 2.0, 3.0]]


@pytest.mark.parametrize("value, match", [
    ([[1, 2]], r"v must have shape \(V, 3\), got \(1, 2\)"),
    ([1, 2, 3], r"v must have shape \(V, 3\), got \(3\)"),
    ([[1, np.nan, 3]], r"v must be finite, got nan at index \(0, 1\)"),
])
def test_as_array_names_argument_and_problem(value, match):
    with pytest.raises(ValueError, match=match):
        as_array(value, "v", shape=("V", 3))


def test_as_array_rejects_non_numbers_with_type_error():
    with pytest.raises(TypeError, match="v must be an array of float64"):
        as_array([["a", "b", "c"]], "v")


def test_as_array_min_length():
    with pytest.raises(ValueError, match="at least 2 entries, got 1"):
        as_array([[0, 0, 0]], "v", shape=("V", 3), min_length=2)


def test_index_array_range_and_type():
    assert as_index_array([0, 4], "ids", upper=5).dtype == np.int64
    with pytest.raises(ValueError, match=r"ids must lie in \[0, 5\), got -1 at position 1"):
        as_index_array([0, -1], "ids", upper=5)
    with pytest.raises(TypeError, match="integer indices"):
        as_index_array([0.5], "ids", upper=5)
