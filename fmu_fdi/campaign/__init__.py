"""Fault-injection campaigns: Monte-Carlo co-simulation of plant and diagnostic FMUs at scale.

- :class:`CampaignSpec` — the campaign file (TOML, ``fmu-fdi-campaign/1``) and its runs.
- :func:`run_campaign` — runs them serially, on a process pool or on Dask; results appended to
  ``runs.jsonl`` as they finish, ``resume`` skips the finished ones.
- :func:`aggregate` — false-alarm rates and mean time between false alarms with exact
  (Clopper–Pearson) intervals, detection probability against fault size, delays, isolation
  confusion matrix, threshold sweep and the threshold_scale meeting a false-alarm target.
- :func:`write_report` — one self-contained HTML report with its plots, plus CSV tables.
"""
from .aggregate import aggregate, clopper_pearson
from .report import write_report
from .runner import CampaignResults, read_results, run_campaign
from .spec import CampaignError, CampaignSpec, Run

__all__ = ["CampaignSpec", "Run", "CampaignError", "run_campaign", "read_results", "CampaignResults",
           "aggregate", "clopper_pearson", "write_report"]
