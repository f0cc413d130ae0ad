"""coordinator/buffers.py: an append-only array, of values or of rows, that keeps what was
appended in order through its doublings."""

import numpy as np

from coordinator.buffers import Appendable


def test_values_and_rows_come_back_in_order_through_doublings():
    rng = np.random.default_rng(0)
    values, rows = Appendable(np.int64), Appendable(float, np.empty((0, 3)))
    want_values, want_rows = [], []
    for k in rng.integers(0, 40, 30):
        v, r = rng.integers(0, 100, k), rng.random((k, 3))
        values.extend(v)
        rows.extend(r)
        want_values.extend(v.tolist())
        want_rows.extend(r.tolist())
        assert np.array_equal(values.view, want_values)
        assert rows.view.shape == (len(want_rows), 3) and np.array_equal(rows.view, np.reshape(want_rows, (-1, 3)))
    assert len(values.data) > 16 and len(rows.data) > 16  # it grew
