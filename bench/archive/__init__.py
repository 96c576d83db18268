"""Campaign archives at scale: every campaign file under some directories indexed into Parquet.

:mod:`~bench.archive.columns` declares the index's columns and version; :mod:`~bench.archive.files`
finds the campaign files and tells what may be read; :mod:`~bench.archive.rows` turns one file into
rows (its metadata, runs, stored results and the identification of an analysis in memory);
:mod:`~bench.archive.store` keeps the index on disk as Parquet parts; :mod:`~bench.archive.build`
plans an index run and runs it on Dask (a local cluster of processes, or a ``dask.distributed``
cluster); :mod:`~bench.archive.trends` draws the archive's trends from an index. docs/index.md
describes the columns, the queries and the cost model.
"""
