"""nodes.heap: the C heap's free pages go back to the operating system (glibc), measured in the process's RSS."""
import platform

from bearing_id.nodes.heap import release_free_heap
import numpy as np
import pytest


def rss_mib() -> float:
    """Resident set size of this process [MiB] (Linux /proc)."""
    with open('/proc/self/statm') as fh:
        return int(fh.read().split()[1]) * 4096 / 2 ** 20


@pytest.mark.skipif(platform.system() != 'Linux' or platform.libc_ver()[0] != 'glibc', reason='glibc malloc_trim only')
def test_freed_heap_pages_under_a_live_block_are_returned():
    """
    1600 arrays of 64 kB (below glibc's mmap threshold: heap), every one freed but the last, which pins the top.

    A plain free cannot shrink a heap whose top is live: ~100 MiB stay resident.  After release_free_heap() at least
    80 of them are back with the OS (the pages of free chunks inside the heap are released too).
    """
    blocks = [np.ones(8192) for _ in range(1600)]      # 64 kB each, touched
    last = blocks[-1]
    del blocks
    before = rss_mib()
    assert release_free_heap() is True
    after = rss_mib()
    assert before - after >= 80, (before, after)
    assert last.sum() == 8192
