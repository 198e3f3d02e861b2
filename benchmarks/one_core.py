"""Import first in a benchmark script: BLAS (OpenMP, OpenBLAS, MKL) and numba run one thread each,
so figures are the cost on one core.  An environment that sets these already wins; ``SET`` names
the variables set here (a script drops them for commands run as a user runs them)."""

import os

SET = tuple(
    v
    for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
    if v not in os.environ
)
for _var in SET:
    os.environ[_var] = "1"
