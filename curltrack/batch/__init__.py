"""Campaigns: ``curltrack batch`` over a folder of videos, in parallel with Dask.

Modules, in the order data flows:

- :mod:`~curltrack.batch.jobs` — the videos of a folder, one :class:`ShotJob` per shot,
  content digests and the key that makes a finished shot recognisable;
- :mod:`~curltrack.batch.split` — shots in a session video (rest -> release -> stop);
- :mod:`~curltrack.batch.shot` — :func:`process_shot`, the task run on a worker:
  skip if finished, else track + fit, record failures, write the done-manifest last;
- :mod:`~curltrack.batch.pipeline` — the per-shot work (``track`` -> ``fit``);
- :mod:`~curltrack.batch.runner` — :func:`run_batch`: local cluster or a scheduler
  address, progress, summary;
- :mod:`~curltrack.batch.table` — the campaign table (``campaign.parquet`` / ``.csv``);
- :mod:`~curltrack.batch.report` — the paper's campaign plots and ``report.html``.
"""

from .jobs import BatchOptions, ShotJob, find_videos, plan_jobs
from .runner import BatchSummary, open_client, run_batch
from .shot import process_shot
from .table import build_table, read_campaign, read_shot_metadata

__all__ = ["BatchOptions", "BatchSummary", "ShotJob", "build_table", "find_videos",
           "open_client", "plan_jobs", "process_shot", "read_campaign",
           "read_shot_metadata", "run_batch"]
