"""wfs-bench: the test-bench controller for the dynamic testing of wheel force sensors.

Importing the package limits the BLAS and OpenMP libraries to one thread each, unless the
environment says otherwise, before numpy is loaded: the bench's linear algebra works on small
matrices, while its own threads (engine, links, simulated devices) need the cores; BLAS worker
threads that spin beside them halved the speed of a campaign on the 2-core machine
(`benchmarks/campaign_speed.py`).
"""

import os

#: The libraries' thread counts the package sets to one (a value the environment holds is kept).
ONE_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

for _variable in ONE_THREAD_VARIABLES:
    os.environ.setdefault(_variable, "1")
