"""How far ahead of the head batches are drawn (coordinator/driver/lead.py) and the
pipeline's rule that follows it: fewer runs in flight where the runs are fast, the full
pipeline elsewhere, never a different committed sequence (tests/farm/test_virtual.py)."""

import math
import numpy as np

from coordinator.driver.lead import FAST_RUN_S, MIN_SHARE, Lead
from coordinator.driver.pipeline import Pipeline


def test_the_lead_shrinks_while_the_head_never_waits_and_grows_when_it_does():
    lead = Lead(adaptive=True)
    assert lead.runs(1000, 2, 1e-5) == 1000  # at first the full pipeline: a batch ahead
    for _ in range(200):
        lead.reached(ahead=True)
    assert lead.share == MIN_SHARE and lead.runs(1000, 2, 1e-5) == 1000 * MIN_SHARE
    lead.waited()
    lead.reached(ahead=True)
    assert MIN_SHARE < lead.share < 1
    lead.reached(ahead=True)  # the wait is counted once
    assert lead.share < MIN_SHARE + 1 / 8
    for _ in range(20):
        lead.waited()
        lead.reached(ahead=True)
    assert lead.share == 1.0  # the workers are the bottleneck: the full pipeline again
    lead.waited()
    lead.reached(ahead=False)  # a batch drawn where the head stood (a round's first): no one's fault
    lead.reached(ahead=True)
    assert lead.share < 1.0


def test_slow_or_unmeasured_runs_and_a_fixed_window_draw_the_full_pipeline():
    lead = Lead(adaptive=True)
    lead.runs(1000, 2, 1e-5)
    for _ in range(50):
        lead.reached(ahead=True)
    assert lead.share < 1
    assert lead.runs(1000, 2, None) == math.inf  # nothing measured yet
    assert lead.runs(1000, 2, FAST_RUN_S) == math.inf
    fixed = Lead(adaptive=False)  # deferred counting or an in-process executor
    fixed.reached(ahead=True)
    assert fixed.share == 1.0 and fixed.runs(1000, 2, 1e-6) == math.inf


class _Launcher:
    """Draws whose ids are their indices; submit records what is sent."""

    def __init__(self):
        self.sent = []

    def starts(self, ids):
        return np.zeros((len(ids), 1))

    def submit(self, first, starts):
        self.sent.append((first, len(starts)))
        return [len(self.sent)]


class _Draws:
    """Draws of the given indices (the pipeline reads only their ids and count)."""

    def __init__(self, indices):
        self.ids = indices

    def __len__(self):
        return len(self.ids)


_draw = _Draws


def test_the_next_batch_is_drawn_once_the_runs_ahead_fall_to_the_lead():
    lead = Lead(adaptive=True)
    lead.share = 0.25
    pipeline = Pipeline(_Launcher(), lead=lead)
    pipeline.fill(0, 1000, 2, 10_000, _draw, run_s=1e-5)
    assert [(p.first_index, len(p)) for p in pipeline] == [(0, 1000)]  # 1,000 ahead > 250
    pipeline.fill(749, 1000, 2, 10_000, _draw, run_s=1e-5)
    assert len(list(pipeline)) == 1  # 251 ahead
    pipeline.fill(750, 1000, 2, 10_000, _draw, run_s=1e-5)
    assert [(p.first_index, p.drawn_at) for p in pipeline] == [(0, 0), (1000, 750)]
    # at the full share, the old pipeline whatever the batches' sizes: a larger batch ahead
    # (a round's first) does not hold the next one back
    lead.share = 1.0
    pipeline = Pipeline(_Launcher(), lead=lead)
    pipeline.fill(0, 2000, 2, 10_000, _draw, run_s=1e-5)
    assert [(p.first_index, len(p)) for p in pipeline] == [(0, 2000), (2000, 2000)]
    pipeline.fill(2000, 1000, 2, 10_000, _draw, run_s=1e-5)  # the head entered the second: 2,000 ahead
    assert [(p.first_index, len(p)) for p in pipeline] == [(0, 2000), (2000, 2000), (4000, 1000)]
    # fixed (a deterministic certification's order) or slow runs: the full pipeline at once
    for kwargs in ({"run_s": 1e-5, "fixed": True}, {"run_s": 1.0}):
        pipeline = Pipeline(_Launcher(), lead=lead)
        pipeline.fill(0, 1000, 2, 10_000, _draw, **kwargs)
        assert [p.first_index for p in pipeline] == [0, 1000]
