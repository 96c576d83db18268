"""``python -m bench.cli``: the ``wfsbench`` command without its console script."""

import sys

from bench.cli.main import main

sys.exit(main())
