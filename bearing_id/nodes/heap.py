"""
Give the C heap's free pages back to the operating system after a burst of allocations (glibc ``malloc_trim``).

kf_estimator's builder thread builds one filter model per speed band a ramp crosses (~160 over the packaged rig's
run-up, each with temporary arrays of a few hundred kB: state space, matrix exponential, Riccati solve).  glibc keeps
what they free in its arenas, so a run-up left the process ~40 MB larger than the models it keeps (one estimator
core, 20 s dwells, 8192-sample blocks: 232 MB against 194 MB after a trim).  Where the C library has no
``malloc_trim`` (musl, macOS) nothing is done.
"""
import ctypes


def _trim_function():
    """
    Return glibc's ``malloc_trim`` (int -> int), or None where the C library has none.

    Looked up among the symbols the process has already loaded (``CDLL(None)``): ``ctypes.util.find_library`` would
    run ``ldconfig`` in a subprocess at every node's import (~5 ms) to find the same library.
    """
    try:
        fn = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn


_TRIM = _trim_function()


def release_free_heap() -> bool:
    """Return the C heap's free memory to the operating system; True when the C library could (glibc)."""
    if _TRIM is None:
        return False
    _TRIM(0)
    return True
