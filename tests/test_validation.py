import numpy as np
import pytest

from faceanim.validation import as_array, as_index_array


def test_as_array_converts_and_keeps_values():
    out = as_array([[1, 2, 3]], "v", shape=("V", 3))
    assert out.dtype == np.float64 and out.flags.c_contiguous
    assert out.tolist() == [[1.0, 2.0, 3.0]]


@pytest.mark.parametrize("value, match", [
    ([[1, 2]], r"v must have shape \(V, 3\), got \(1, 2\)"),
    ([1, 2, 3], r"v must have shape \(V, 3\), got \(3,\)"),
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


def test_frozen_arrays_are_read_only_and_share_nothing_the_caller_can_write():
    mine = np.zeros((2, 3))
    kept = as_array(mine, "v", frozen=True)
    assert not kept.flags.writeable and not np.shares_memory(kept, mine)
    mine[0, 0] = 5.0  # the caller's array stays the caller's
    assert kept[0, 0] == 0.0
    with pytest.raises(ValueError, match="read-only"):
        kept[0, 0] = 1.0
    assert as_array(kept, "v", frozen=True) is kept  # owned and read-only already: taken, not copied
    view = kept[:1]  # a read-only view of someone's array is copied (its owner might be writable)
    assert as_array(view, "v", frozen=True).base is None
    from_list = as_array([[1, 2, 3]], "v", frozen=True)
    assert not from_list.flags.writeable and from_list.flags.owndata
    ids = as_index_array(np.array([0, 1]), "ids", upper=2, frozen=True)
    assert not ids.flags.writeable


def test_a_bool_array_takes_only_truth_values():
    assert as_array([1, 0, True], "valid", dtype=bool).tolist() == [True, False, True]
    with pytest.raises(ValueError, match=r"valid must hold booleans \(or 0 and 1\), got 0.5 at index \(1,\)"):
        as_array([1, 0.5], "valid", dtype=bool)


def test_restore_frozen_marks_unpickled_arrays_read_only():
    from faceanim.validation import restore_frozen

    class Holder:
        pass

    holder = Holder()
    restore_frozen(holder, {"a": np.zeros(3), "n": 4})
    assert not holder.a.flags.writeable and holder.n == 4
