"""summary.json's holdout in words (coordinator/holdout.py runs it)."""

from __future__ import annotations


def _share(k: int, n: int, interval) -> str:
    low, high = interval
    return f"{k:,} of {n:,} ({100 * k / n if n else 0:.3g} %, 95 % interval {100 * low:.3g} to {100 * high:.3g} %)"


def describe_holdout(h: dict) -> str:
    """One line: how many fresh uniform starts the set claimed and got wrong."""
    text = (f"{h['runs']:,} fresh uniform starts: in the set but failing "
            f"{_share(h['overclaims'], h['in_set'], h['overclaim_interval'])}")
    if h.get("deterministic"):
        text += f"; outside it but safe {_share(h['misses'], h['runs'] - h['in_set'], h['miss_interval'])}"
    return text
