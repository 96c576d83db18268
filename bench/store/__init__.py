"""The HDF5 campaign store: one file per campaign, a group per run (schema in ``docs/hdf5.md``).

:class:`CampaignWriter` / :class:`RunWriter` write a campaign incrementally and durably as sample
blocks arrive; :func:`open_campaign` reads any file that follows the schema into the analysis's
records. Names, versions and dtypes live in :mod:`bench.store.schema`.
"""

from bench.store.reader import CampaignFile, Event, RunView, open_campaign
from bench.store.schema import SCHEMA_NAME, SCHEMA_VERSION, StoreError
from bench.store.writer import CampaignWriter, RunWriter, add_results

__all__ = [
    "SCHEMA_NAME",
    "SCHEMA_VERSION",
    "CampaignFile",
    "CampaignWriter",
    "Event",
    "RunView",
    "RunWriter",
    "StoreError",
    "add_results",
    "open_campaign",
]
