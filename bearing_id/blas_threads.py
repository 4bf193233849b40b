"""
One BLAS thread per process, unless the user chose otherwise: imported for its effect by the process entry points.

The linear algebra here is small and dense (matrices of at most a few hundred rows: 44-268 DOF models, 2x2 to 20x20
least-squares blocks, tall-skinny QR of one window).  On such sizes a BLAS thread pool costs more than it gains:
OpenBLAS's threads spin and hand work back and forth, numpy and scipy each bring an OpenBLAS with its own pool, and
with the three nodes on two cores they also fight each other: on the 9-speed benchmark files (benchmarks/bench_speed.py)
a pool of two doubled the CPU of ``bearing-id identify`` and ``diagnose`` without shortening their wall time.

The thread counts are read by the BLAS library when numpy is first imported, so this module must be imported before
numpy: the console scripts (:mod:`bearing_id.cli`, the nodes' package :mod:`bearing_id.nodes`) import it first.  A
user's own setting always wins: nothing is changed when any of the variables below is already set in the
environment (``OPENBLAS_NUM_THREADS=2 bearing-id identify ...`` uses two threads).  A program that imports
numpy before bearing_id keeps whatever its BLAS was started with.
"""
import os

THREAD_VARS = ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS', 'GOTO_NUM_THREADS',
               'BLIS_NUM_THREADS', 'VECLIB_MAXIMUM_THREADS')


def limit_to_one(environ=os.environ) -> bool:
    """Set the BLAS thread counts of ``environ`` to 1 when none is set; return True when it set them."""
    if any(environ.get(v) for v in THREAD_VARS):
        return False
    for v in ('OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'BLIS_NUM_THREADS', 'VECLIB_MAXIMUM_THREADS'):
        environ[v] = '1'
    return True


limit_to_one()
