"""The identity of a quantified safe set: an order-independent hash of its boxes."""

from __future__ import annotations

import hashlib

import numpy as np


def result_hash(centres: np.ndarray, half_width: float) -> str:
    """Order-independent hash of a safe set (sorted rows, exact float64 bytes)."""
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    order = np.lexsort(centres.T[::-1]) if len(centres) else np.zeros(0, dtype=np.int64)
    h = hashlib.sha256()
    h.update(np.float64(half_width).tobytes())
    h.update(np.ascontiguousarray(centres[order]).tobytes())
    return h.hexdigest()[:16]
