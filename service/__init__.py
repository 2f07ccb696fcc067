"""HTTP skin over the engine."""

import os

# One BLAS thread in the service process, set before numpy is first imported: the analyses
# answered here (first and second order of small linkages, see service.workers) are far too
# small to gain from threads, and on a loaded machine threaded BLAS made a 60 x 60 SVD take
# 0.13 s instead of 0.7 ms. The engine workers get the same (service.workers).
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
