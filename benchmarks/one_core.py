"""Import first in a benchmark script: BLAS (OpenMP, OpenBLAS, MKL) and numba run one thread each,
so figures are the cost on one core.  An environment that sets these already wins."""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
