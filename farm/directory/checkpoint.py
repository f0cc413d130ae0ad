"""Checkpoint and restore of one side's campaign (farm/jobs/side_campaign.py).

A checkpoint is taken at a chunk boundary: the committed runs since the last one go to
the ledger (and the state-changing failures kept for it to an MCAP recording named by
that ledger segment), then the algorithm's, the driver's and the adversary's state go to
the journal (farm/directory/journal.py) with the ledger's digests. Restoring checks the
config hash and the ledger against the checkpoint before anything is used, so a resumed
campaign re-simulates exactly what it had drawn and reaches the result an uninterrupted
one does.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from coordinator.adversary import AdversarySearch
from coordinator.algorithm import Algorithm
from coordinator.driver import Campaign, DriverState
from farm.directory.journal import Journal
from farm.directory.recording import write_recording
from farm.directory.storage import CampaignError, Ledger
from farm.execution.memory import release_freed_memory
from scenarios.base import Scenario
from scenarios.search import SearchActions
from scenarios.version import __version__


@dataclass(frozen=True)
class Stamp:
    """What one side's checkpoints and recordings are stamped and placed with."""

    directory: Path  # the side's directory (the campaign's, or DIR/sides/<side>)
    side: str  # "total", or a side's name (fleet3: "lead", "rear")
    config_hash: str
    seed: int
    scenario: Scenario


@dataclass
class Restored:
    """What a checkpoint holds besides the algorithm state (already loaded)."""

    driver: DriverState
    adversary: AdversarySearch | None


def save(campaign: Campaign, ledger: Ledger, journal: Journal, stamp: Stamp) -> None:
    release_freed_memory()  # before the state's arrays are gathered and written
    algorithm = campaign.committed_algorithm()  # the state the driver's is (coordinator/driver/speculation.py)
    ledger.append(campaign.log.take())
    recordings = campaign.take_recordings()
    if recordings:
        _write_recording(stamp, ledger, recordings)
    arrays = {f"algo.{k}": v for k, v in algorithm.state().items()}
    driver_arrays, driver_meta = campaign.state()
    arrays.update(driver_arrays)
    if campaign.adversary is not None:
        arrays.update(campaign.adversary.state())
    meta = {"config_hash": stamp.config_hash, "algorithm": algorithm.name, "side": stamp.side, **driver_meta,
            "ledger_digests": ledger.digests, "ledger_rows": ledger.rows}
    journal.save(arrays, {f"algo.{k}" for k in algorithm.append_only}, algorithm.state_epoch, meta)


def _write_recording(stamp: Stamp, ledger: Ledger, runs: list[dict]) -> None:
    rec_dir = stamp.directory / "recordings"
    rec_dir.mkdir(exist_ok=True)
    scenario = stamp.scenario
    # named by the ledger segment they go with (just written), so that resume can drop
    # recordings of a checkpoint that never completed
    write_recording(rec_dir / f"runs-{ledger.segments - 1:06d}.mcap", scenario_name=scenario.name,
                    state_names=list(scenario.state_names), dt=scenario.dt, runs=runs,
                    metadata={"config_hash": stamp.config_hash, "seed": str(stamp.seed), "side": stamp.side,
                              "scenario_farm_version": __version__})


def restore(journal: Journal, ledger: Ledger, algorithm: Algorithm, policy, stamp: Stamp) -> Restored:
    """Load the side's checkpoint into ``algorithm``; -> the driver's and the adversary's
    state (an adversary when ``policy`` is the search's). Raises CampaignError (nothing
    changed) for a checkpoint of another config or a damaged one."""
    arrays, meta = journal.load()
    if meta.get("config_hash") != stamp.config_hash:
        raise CampaignError(f"{journal.main}: stamped with config hash {meta.get('config_hash')}, "
                            f"the config hashes to {stamp.config_hash}; nothing was changed")
    try:
        ledger.verify_and_trim(meta["ledger_digests"], meta["ledger_rows"])
        algorithm.load_state({k[5:]: v for k, v in arrays.items() if k.startswith("algo.")})
        algorithm.state_epoch = int(meta.get("epoch", 0))
        driver = DriverState.read(arrays, meta)
        adversary = None
        if isinstance(policy, SearchActions):
            adversary = AdversarySearch(policy, stamp.seed)
            adversary.load_state(arrays)
    except KeyError as exc:
        raise CampaignError(f"{journal.main}: checkpoint lacks {exc} (damaged?); nothing was changed") \
            from None
    except (TypeError, ValueError) as exc:
        raise CampaignError(f"{journal.main}: checkpoint does not read ({exc}; damaged?); nothing was changed") \
            from None
    return Restored(driver, adversary)
