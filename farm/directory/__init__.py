"""The campaign directory: what is written where (storage, ledger), atomically (files), checkpoints (journal), records and recordings."""
