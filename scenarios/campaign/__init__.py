"""``hilnav campaign``: Monte Carlo sweeps over seeds and parameter grids, on Dask.

A campaign is the cartesian product *scenario files x grid points x seeds*. A grid point is one
choice per ``--vary`` key (``{"imu": "consumer-mems", "bridge": "gmdh"}``); the keys are
seed-independent scenario fields listed in :data:`VARY_KEYS`. Each run is a lockstep
:func:`~scenarios.runner.run_scenario` call: independent of every other run and deterministic
for its inputs, so the numbers do not depend on which worker (or machine) flew it.

Layout of the output folder::

    DIR/runs/<id>/summary.json     one per finished run (written last, atomically)
    DIR/runs/<id>/error.txt        a run that raised: the traceback (the run is retried on resume)
    DIR/runs/<id>/run.json         what the run was: scenario, seed, grid point
    DIR/campaign.json              aggregate statistics, the run list, failed runs
    DIR/campaign.md                the same as Markdown tables
    DIR/distributions.png          error distributions per grid point

``<id>`` is a hash of the scenario file's bytes, the seed and the grid point, so running the same
campaign again into the same folder skips every run that has a ``summary.json`` (counted as
*resumed*) and only flies the missing or failed ones. The id covers neither the hilnav code
nor a plan file the scenario refers to by path: after changing either, start a new folder.

Execution: a ``dask.distributed`` ``LocalCluster`` with one single-threaded worker process per
core by default, or an existing cluster (``scheduler="tcp://HOST:8786"``) whose workers have the
same hilnav installed. Scenarios are loaded and the grid applied on the client; workers receive
the resulting :class:`~scenarios.schema.Scenario` objects, fly them in a private temporary
folder and send the run's files back, so workers need neither the scenario files nor a shared
file system. Before the first submission every worker imports the run's modules once
(:func:`~scenarios.campaign.execute.warm_up`, ``execution.warm_up_s``), so that one-off cost is
not charged to whichever runs come first. A run that raises is recorded (``error.txt`` and
``campaign.json["failed"]``), never silently dropped.

Aggregation reads the summaries back sorted by run id, so it is the same whatever the order in
which the runs completed. Per scenario x grid point (the bridging and altitude methods are part
of the grid point when varied, and are named in every group), every metric gets ``mean``,
``p95`` (linear interpolation between order statistics), ``worst`` (the maximum: every metric is
an error) and ``n``. Outage metrics are pooled over every outage of every run of the group
(``n`` counts outages); GNSS-on metrics have one value per run. Wall-clock timings are kept out
of the aggregate (they do depend on the machine).
"""

from scenarios.campaign.aggregate import aggregate, stats
from scenarios.campaign.execute import CampaignResult, run_campaign
from scenarios.campaign.plan import (
    VARY_KEYS,
    apply_point,
    grid_points,
    parse_vary,
    plan_runs,
    run_id,
)

__all__ = [
    "VARY_KEYS", "CampaignResult", "aggregate", "apply_point", "grid_points", "parse_vary",
    "plan_runs", "run_campaign", "run_id", "stats",
]
