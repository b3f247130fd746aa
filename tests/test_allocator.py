"""components.cli.allocator: freed blocks of a few MB stay in the process, so allocating them again
costs no page faults (counted by the kernel, resource.getrusage)."""
import subprocess
import sys

import pytest

from components.cli.allocator import glibc_mallopt

CHURN = """
import resource, sys
import numpy as np
if sys.argv[1] == "keep":
    from components.cli.allocator import keep_freed_memory
    assert keep_freed_memory()
def chunk():  # what a chunk of the log does: several arrays of a few MB at once, then none
    arrays = [np.ones(600_000) for _ in range(10)]  # 4.8 MB each, every page written
    del arrays
chunk()  # the first chunk faults its pages in either way
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):
    chunk()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _faults(mode: str) -> int:
    out = subprocess.run([sys.executable, "-c", CHURN, mode], capture_output=True, text=True, check=True)
    return int(out.stdout)


@pytest.mark.skipif(glibc_mallopt() is None, reason="not glibc's malloc: nothing to set")
def test_freed_blocks_are_reused_without_page_faults():
    pages = 20 * 10 * 600_000 * 8 // 4096  # every page of 20 chunks, were each faulted in anew
    assert _faults("default") > pages // 4  # glibc's default gives the freed heap top back (~45 %)
    assert _faults("keep") < pages // 100  # kept: a few pages' bookkeeping
