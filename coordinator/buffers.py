"""An array that only grows at its end (values, or rows of a 2-D array): appends cost
O(1) amortized (doubling)."""

from __future__ import annotations

import numpy as np


class Appendable:
    """The first ``size`` values (or rows: ``initial`` of shape (k, n)) of a buffer that
    doubles when full (``view``: them)."""

    def __init__(self, dtype, initial=()):
        data = np.asarray(initial, dtype=dtype)
        self.data = np.empty((max(16, 2 * len(data)), *data.shape[1:]), dtype=dtype)
        self.data[: len(data)] = data
        self.size = len(data)

    def extend(self, values: np.ndarray) -> None:
        need = self.size + len(values)
        if need > len(self.data):
            grown = np.empty((max(need, 2 * len(self.data)), *self.data.shape[1:]), dtype=self.data.dtype)
            grown[: self.size] = self.data[: self.size]
            self.data = grown
        self.data[self.size : need] = values
        self.size = need

    @property
    def view(self) -> np.ndarray:
        return self.data[: self.size]
