"""Exports of a campaign file to the formats other tools read (docs/export.md), one module each:

- :mod:`~bench.export.mdf4`: every recorded channel with its unit and role, the runs' conditions
  and the campaign's metadata, as ASAM MDF 4 (asammdf);
- :mod:`~bench.export.uff58`: the dwell and sweep FRFs the analysis gives, raw and compensated,
  with their uncertainty or coherence, as universal file format dataset 58 records (pyuff);
- :mod:`~bench.export.csv_files`: one CSV file per run with a units row, and the mapping with which
  ``wfsbench import-csv`` reads them back;
- :mod:`~bench.export.rpc3`: one MTS RPC III time-history file per run;
- :mod:`~bench.export.common`: the error, the runs taken, outputs that appear whole or not at all.
"""
