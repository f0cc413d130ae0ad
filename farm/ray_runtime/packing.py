"""Small task payloads as one bytes object each way (a chunk's summary back, a change
block out, experience replay's pieces both ways): Ray serializes every numpy array it
finds as a buffer of its own, which costs the driver more per array than a pickle of the
whole object in one buffer when the arrays are small (a summary holds a dozen, a change
block one per change, a round end's replay a few per stored piece, hundreds of pieces;
docs/benchmarks.md, "2026-11-29, evening" and "late evening"). Only between the driver and
its own actors: nothing here is written to a file."""

from __future__ import annotations

import pickle


def pack(value) -> bytes:
    """``value`` (arrays, dataclasses of them, tuples, lists) as one in-band pickle."""
    return pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)


def unpack(blob):
    """The value ``pack`` made: bytes from this driver or its actors, never a file."""
    return pickle.loads(blob)
