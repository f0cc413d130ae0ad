"""Checkpoint and restore of one facet campaign (farm/jobs/side_campaign.py).

A checkpoint is taken at a chunk boundary: the committed runs since the last one go to
the ledger (and the state-changing failures kept for it to an MCAP recording named by
that ledger segment), then the algorithm's, the driver's and the adversary's state go to
the journal (farm/directory/journal.py) with the ledger's digests. Restoring checks the config hash
and the ledger against the checkpoint before anything is used, so a resumed campaign
re-simulates exactly what it had drawn and reaches the result an uninterrupted one does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from coordinator.adversary import AdversarySearch
from coordinator.campaign import DriverState
from farm.execution.memory import release_freed_memory
from farm.directory.storage import CampaignError
from scenarios.search import SearchActions
from scenarios.version import __version__

if TYPE_CHECKING:
    from farm.jobs.side_campaign import FacetCampaign


@dataclass
class Restored:
    """What a checkpoint holds besides the algorithm state (already loaded)."""

    driver: DriverState
    adversary: AdversarySearch | None


def save(facet: "FacetCampaign") -> None:
    release_freed_memory()  # before the state's arrays are gathered and written
    campaign = facet.campaign
    algorithm = campaign.committed_algorithm()  # the state the driver's is (coordinator/speculation.py)
    facet.ledger.append(campaign.log.take())
    recordings = campaign.take_recordings()
    if recordings:
        _write_recording(facet, recordings)
    arrays = {f"algo.{k}": v for k, v in algorithm.state().items()}
    driver_arrays, driver_meta = campaign.state()
    arrays.update(driver_arrays)
    if campaign.adversary is not None:
        arrays.update(campaign.adversary.state())
    meta = {"config_hash": facet.config_hash, "algorithm": algorithm.name, "part": facet.label, **driver_meta,
            "ledger_digests": facet.ledger.digests, "ledger_rows": facet.ledger.rows}
    facet.journal.save(arrays, {f"algo.{k}" for k in algorithm.append_only}, algorithm.state_epoch, meta)


def _write_recording(facet: "FacetCampaign", runs: list[dict]) -> None:
    from farm.directory.recording import write_recording

    rec_dir = facet.directory / "recordings"
    rec_dir.mkdir(exist_ok=True)
    scenario = facet.scenario
    # named by the ledger segment they go with (just written), so that resume can drop
    # recordings of a checkpoint that never completed
    write_recording(rec_dir / f"runs-{facet.ledger.segments - 1:06d}.mcap", scenario_name=scenario.name,
                    state_names=list(scenario.state_names), dt=scenario.dt, runs=runs,
                    metadata={"config_hash": facet.config_hash, "seed": str(facet.cfg.farm.seed),
                              "part": facet.label, "scenario_farm_version": __version__})


def restore(facet: "FacetCampaign") -> Restored:
    """Load the facet's checkpoint into its algorithm; -> the driver's and the adversary's
    state. Raises CampaignError (nothing changed) for a checkpoint of another config or a
    damaged one."""
    arrays, meta = facet.journal.load()
    if meta.get("config_hash") != facet.config_hash:
        raise CampaignError(f"{facet.journal.main}: stamped with config hash {meta.get('config_hash')}, "
                            f"the config hashes to {facet.config_hash}; nothing was changed")
    try:
        facet.ledger.verify_and_trim(meta["ledger_digests"], meta["ledger_rows"])
        facet.algorithm.load_state({k[5:]: v for k, v in arrays.items() if k.startswith("algo.")})
        facet.algorithm.state_epoch = int(meta.get("epoch", 0))
        driver = DriverState.read(arrays, meta)
        adversary = None
        if isinstance(facet.policy, SearchActions):
            adversary = AdversarySearch(facet.policy, facet.cfg.farm.seed)
            adversary.load_state(arrays)
    except (KeyError, TypeError, ValueError) as exc:
        raise CampaignError(f"{facet.journal.main}: checkpoint lacks {exc} (damaged?); nothing was changed") \
            from None
    return Restored(driver, adversary)
