"""Independent fits on every core: how many worker processes (:func:`workers`), a map over forked
workers (:func:`forked_map`: the diagnosis's effect fits, the whole fit's structures), and one BLAS
thread in each worker (:func:`limit_blas_threads`, also the local batch pool's initializer), since
the pools are the parallelism."""
from __future__ import annotations

import multiprocessing
import os


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


def workers() -> int:
    """Processes independent fits may run on: the cores this process may use (``HWID_WORKERS`` caps
    them; 1 runs them in this process), and 1 inside a daemonic worker (a batch pool's), which may
    not start processes of its own or where ``fork`` is not available."""
    if multiprocessing.current_process().daemon or "fork" not in multiprocessing.get_all_start_methods():
        return 1
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:      # not Linux
        n = os.cpu_count() or 1
    cap = os.environ.get("HWID_WORKERS", "").strip()
    return max(1, min(n, int(cap))) if cap.isdigit() else max(n, 1)


# what a forked worker runs (set in the parent just before the fork, so the children share it
# copy-on-write instead of receiving a pickle of the data)
_SHARED = None


def _run_shared(job):
    return _SHARED(job)


def forked_map(fun, jobs, cost=None) -> list:
    """``[fun(job) for job in jobs]``, in forked workers (one BLAS thread each) where
    :func:`workers` allows more than one; ``fun`` may be a closure (it is not pickled, only the jobs
    and the results are). ``cost(job)``: a job's expected run time, relative; the workers take the
    jobs longest first (a long job handed out last keeps one worker busy while the others idle),
    and the results come back in the order of ``jobs``."""
    global _SHARED
    jobs = list(jobs)
    n = min(workers(), len(jobs))
    if n <= 1:
        return [fun(job) for job in jobs]
    order = sorted(range(len(jobs)), key=lambda i: -cost(jobs[i])) if cost else list(range(len(jobs)))
    _SHARED = fun
    try:
        with multiprocessing.get_context("fork").Pool(n, initializer=limit_blas_threads) as pool:
            done = pool.map(_run_shared, [jobs[i] for i in order], chunksize=1)
    finally:
        _SHARED = None
    out = [None] * len(jobs)
    for i, r in zip(order, done):
        out[i] = r
    return out
