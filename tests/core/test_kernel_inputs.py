"""engine/core/kernel_inputs.py: the compiled kernels' inputs made contiguous and read-only without
changing a value, and without a copy where none is needed."""
import numpy as np

from engine.core.kernel_inputs import contiguous, fitted, read_only


def test_read_only_is_a_view_that_cannot_be_written():
    a = np.arange(6.0)
    view = read_only(a)
    assert not view.flags.writeable and np.shares_memory(view, a) and a.flags.writeable
    b = np.broadcast_to(np.ones(3), (2, 3))            # already read-only: returned as it is
    assert read_only(b) is b


def test_fitted_keeps_the_values_and_makes_one_signature():
    rows = np.arange(12.0).reshape(4, 3).T              # (3, 4), not contiguous
    out = fitted(rows, (3, 4))
    assert out.flags.c_contiguous and not out.flags.writeable and np.array_equal(out, rows)
    same = np.arange(4.0)
    assert np.shares_memory(fitted(same, (4,)), same)   # contiguous and of its shape: no copy
    scalar = fitted(-0.0, (5,))
    assert scalar.shape == (5,) and np.all(np.signbit(scalar)) and not scalar.flags.writeable
    flags = fitted(np.array([1, 0, 2]), (3,), np.bool_)
    assert flags.dtype == np.bool_ and flags.tolist() == [True, False, True]


def test_contiguous_copies_only_what_is_not():
    rows = np.arange(12.0).reshape(3, 4)
    assert np.shares_memory(contiguous(rows), rows) and not contiguous(rows).flags.writeable
    column = rows[:, 1]                                  # strided: copied
    out = contiguous(column)
    assert out.flags.c_contiguous and not np.shares_memory(out, rows) and np.array_equal(out, column)
    assert contiguous(np.array([1, 2]), np.int64).dtype == np.int64


def test_control_a_wrong_shape_is_not_broadcast_silently():
    try:
        fitted(np.zeros(3), (4,))
    except ValueError:
        return
    raise AssertionError("a (3,) array fitted to (4,) must fail, not be cut or padded")
