"""The ``wfsbench`` command line: the entry point (:mod:`bench.cli.main`), one module per group of
commands, and the one table of exit codes (:mod:`bench.cli.exit_codes`)."""
