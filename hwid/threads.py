"""How many threads a worker process uses: the pools (local batches, the diagnosis's effect fits)
are the parallelism, so each worker runs one BLAS thread."""
from __future__ import annotations


def limit_blas_threads():
    """One BLAS thread in this process: the initializer of the local pool's workers (the pool is the
    parallelism).

    An OpenBLAS thread pool in each of J workers on J cores only oversubscribes them: its threads
    spin while they wait, and on a loaded machine a run costs 10-20 % more CPU. ``threadpoolctl``
    does this for every BLAS when it is installed; without it the OpenBLAS libraries numpy and scipy
    have loaded are told directly (Linux: found in ``/proc/self/maps``)."""
    import scipy.linalg  # noqa: F401 - loads scipy's OpenBLAS, as numpy's is, so both are limited
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        pass
    else:
        threadpool_limits(limits=1)
        return
    import ctypes
    try:
        with open("/proc/self/maps") as fh:
            libs = {ln.split()[-1] for ln in fh if "openblas" in ln.lower() and ".so" in ln}
    except OSError:
        return
    for path in libs:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in ("openblas_set_num_threads", "openblas_set_num_threads64_",
                     "scipy_openblas_set_num_threads", "scipy_openblas_set_num_threads64_"):
            fn = getattr(lib, name, None)
            if fn is not None:
                fn(1)
