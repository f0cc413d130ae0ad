"""An estimate's committed runs as Parquet segments (``DIR/estimates/<name>/ledger/``), one
row per run: ``sample_index``, ``stage``, ``stratum`` (its index in estimate.json's
``strata``), the start state (a column per state variable), ``outcome`` (failure /
truncated / horizon) and ``steps``; with a second controller also ``outcome_versus`` and
``steps_versus``. Segments are checksummed in the checkpoint as a campaign's are (the
digests and the trim on resume are ``Ledger``'s)."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from farm.directory.files import atomic_write, sha256_file
from farm.directory.storage import Ledger
from scenarios.base import OUTCOME_NAMES


def _outcomes(codes: np.ndarray) -> pa.Array:
    names = pa.array([OUTCOME_NAMES[o] for o in range(1, 4)])
    return pa.DictionaryArray.from_arrays(pa.array(np.asarray(codes, dtype=np.int8) - 1), names).cast(pa.string())


class EstimateLedger(Ledger):
    """Committed batches (``coordinator.estimation.CommittedBatch``) kept until ``flush``."""

    def __init__(self, directory, state_names):
        super().__init__(directory, state_names)
        self.pending: list = []

    def add(self, batch) -> None:
        self.pending.append(batch)

    def flush(self) -> None:
        """The pending batches as one new segment (atomic); its digest joins ``digests``."""
        if not self.pending:
            return
        batches, self.pending = self.pending, []
        cols = {"sample_index": np.concatenate([b.indices for b in batches]),
                "stage": np.concatenate([np.full(len(b.strata), b.stage, dtype=np.int32) for b in batches]),
                "stratum": np.concatenate([b.strata for b in batches]).astype(np.int32)}
        starts = np.concatenate([b.starts for b in batches])
        for i, name in enumerate(self.state_names):
            cols[name] = starts[:, i]
        for k, suffix in enumerate(("", "_versus")[: len(batches[0].outcomes)]):
            cols[f"outcome{suffix}"] = _outcomes(np.concatenate([b.outcomes[k] for b in batches]))
            cols[f"steps{suffix}"] = np.concatenate([b.steps[k] for b in batches]).astype(np.int32)
        self.dir.mkdir(parents=True, exist_ok=True)
        path = self.dir / f"segment-{self.segments:06d}.parquet"
        atomic_write(path, lambda fh: pq.write_table(pa.table(cols), fh))
        self.digests.append(sha256_file(path))
        self.rows += len(cols["sample_index"])
