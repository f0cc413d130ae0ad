"""The campaign driver: the parallel contract (shared/spec/algorithms.md, scaling.md).

One part per job, none of which calls back into the driver:

- ``campaign.py`` (``Campaign``): the loop; commits runs in index order, applies
  changes, ends rounds;
- ``settings.py`` (``CampaignSettings``): what it needs besides the algorithm and executor;
- ``phase.py``: which kind of round it is in (the algorithm's rounds, certification's
  closing rounds, checks or enumeration) and what a round end or a change leads to;
- ``launcher.py``: the executor's side (runs drawn from their own streams, sent, fetched);
- ``pipeline.py``: the batches drawn ahead of the head and their chunks;
- ``lead.py``: how far ahead of the head the next batch is drawn;
- ``exact.py``: coupled counting's question, is a run still what its stream draws now;
- ``replacements.py``: the runs that replace mispredicted ones, queued in due order;
- ``holds.py``: the replacements the head passed before they were back, and what it did past them;
- ``speculation.py``: changes applied past holds, and the state before each;
- ``lookahead.py``: runs launched before the head asks for them (never changes a result);
- ``commit_log.py``, ``recordings.py``: the ledger rows and the failing runs to record;
- ``state.py``: the driver's persisted state (``Counters``, ``DriverState``);
- ``refinement_campaign.py`` (``RefinementCampaign``): the other driver, for margin
  refinement of a deterministic system (waves decided by their starts; no coupling).
"""

from coordinator.driver.campaign import Campaign, Observer
from coordinator.driver.refinement_campaign import RefinementCampaign
from coordinator.driver.settings import CampaignSettings
from coordinator.driver.state import Counters, DriverState

__all__ = ["Campaign", "CampaignSettings", "Counters", "DriverState", "Observer", "RefinementCampaign"]
