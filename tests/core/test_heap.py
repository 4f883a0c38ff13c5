"""kept_heap: a large block freed inside it is reused without new page faults; outside, faulted in again."""

from __future__ import annotations

import ctypes
import resource

import pytest

from labcli.core.heap import _libc, kept_heap

SIZE = 48 * 2**20  # over glibc's largest mmap threshold (32 MiB): served by mmap unless kept


def faults_of_second_block(libc) -> int:
    """Minor page faults of filling a SIZE block after one the same size was filled and freed."""
    libc.malloc.restype = ctypes.c_void_p
    libc.free.argtypes = [ctypes.c_void_p]
    first = libc.malloc(SIZE)
    ctypes.memset(first, 1, SIZE)
    libc.free(first)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    second = libc.malloc(SIZE)
    ctypes.memset(second, 1, SIZE)
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    libc.free(second)
    return faults


@pytest.mark.skipif(_libc() is None, reason="glibc's mallopt is not available here")
def test_a_freed_block_is_reused_inside_kept_heap_and_faulted_in_again_outside():
    libc = _libc()
    pages = SIZE // resource.getpagesize()
    outside = faults_of_second_block(libc)
    with kept_heap():
        inside = faults_of_second_block(libc)
    after = faults_of_second_block(libc)
    assert outside > pages // 2 and after > pages // 2  # a fresh mapping, a page at a time
    assert inside < pages // 20  # the heap's own pages, reused


@pytest.mark.skipif(_libc() is None, reason="glibc's mallopt is not available here")
def test_an_error_inside_kept_heap_passes_through_and_the_thresholds_are_restored():
    with pytest.raises(ValueError, match="inside"):
        with kept_heap():
            raise ValueError("inside")
    assert faults_of_second_block(_libc()) > SIZE // resource.getpagesize() // 2


@pytest.mark.skipif(_libc() is None, reason="glibc's mallopt is not available here")
def test_an_inner_kept_heap_leaves_the_outer_blocks_reuse_in_place():
    pages = SIZE // resource.getpagesize()
    with kept_heap():
        with kept_heap():
            pass
        after_inner = faults_of_second_block(_libc())
    assert after_inner < pages // 20  # still the heap's own pages: the inner exit restored nothing
    assert faults_of_second_block(_libc()) > pages // 2  # the outer exit did
