"""Road measurements of a fleet compensated as one job (``wfsbench compensate CAMPAIGN DIR --out
DIR``): every MDF4 and CSV measurement under some folders compensated with what one campaign
identified, one output per measurement, a Parquet summary of every file.

:mod:`~bench.fleet.summary` declares the summary's columns and keeps it on disk;
:mod:`~bench.fleet.worker` is what a worker does with one measurement (the only place it is read);
:mod:`~bench.fleet.job` plans a run against the summary held (unchanged files are not read) and
runs it on an executor of :mod:`bench.cluster` (this process, or a ``dask.distributed`` cluster).
docs/compensate.md, *Many measurements*, describes the job and its cost.
"""
