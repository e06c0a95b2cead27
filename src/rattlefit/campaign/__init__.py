"""A whole test campaign at once, on a dask.distributed cluster.

:func:`run_campaign` identifies every recording of a manifest (jointly where the manifest
groups them), optionally samples and diagnoses them, and writes a tidy results table, every
run's JSON and one HTML report; work already done is skipped. :func:`simulate_campaign`
writes a synthetic campaign with known truth. The modules: ``manifest`` (what the campaign
holds), ``options``, ``work`` (what a worker does), ``schedule`` (the task graph, resumption,
failures), ``table``, ``report`` and ``synthetic``. Importing this package imports neither
dask nor JAX's compiled programs; :func:`run_campaign` starts or joins the cluster.
"""

from .manifest import Manifest, Unit, read_manifest
from .options import CampaignOptions, ClusterOptions
from .schedule import CampaignResult, run_campaign
from .synthetic import CampaignGrid, SyntheticTruth, simulate_campaign
from .table import read_table

__all__ = [
    "CampaignGrid",
    "CampaignOptions",
    "CampaignResult",
    "ClusterOptions",
    "Manifest",
    "SyntheticTruth",
    "Unit",
    "read_manifest",
    "read_table",
    "run_campaign",
    "simulate_campaign",
]
