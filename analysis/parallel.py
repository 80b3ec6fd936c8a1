"""Independent closed-loop jobs of ``analyze`` and ``verify``, on the toolkit's one Dask machinery.

:func:`map_jobs` is :func:`meanfield.workflows.dask_cluster.map_jobs`: a local Dask cluster by default, the
cluster of an enclosing :func:`meanfield.workflows.dask_cluster.jobs_on` (``--scheduler``) otherwise, as
``meanfield sweep`` runs its jobs.
"""

from __future__ import annotations

from meanfield.workflows.dask_cluster import jobs_on, map_jobs

__all__ = ["map_jobs", "jobs_on"]
