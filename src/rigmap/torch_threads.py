"""How many torch threads a piece of small dense work runs on.

On a busy 2-core machine torch's threads mostly wait for each other on small matrices
and short calls (measured on this project's machine: a 218² batched Cholesky 0.6 ms on
one thread and 8 ms on two; a 150² Cholesky 0.13 ms and 22 ms; a single-pose rig call
about halved), so refinement, the GPLVM fit and interactive posing pin one thread while
they run, and the networks take their thread count from config.

numpy's OpenBLAS keeps its own threads (two here), which torch's setting does not
touch: refinement's GPR products (a learned Jacobian's prediction, 72 quadruped frames
× 250 support poses × 5 809 entries) ran 85-115 ms on two BLAS threads at a load of 7
and 35 ms on one, so ``blas_threads`` pins those alike.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache

import torch
from threadpoolctl import ThreadpoolController


@contextmanager
def torch_threads(threads: int | None) -> Iterator[None]:
    """Run the block with ``threads`` torch threads (``None``: torch's own setting)."""
    if threads is None:
        yield
        return
    previous = torch.get_num_threads()
    torch.set_num_threads(int(threads))
    try:
        yield
    finally:
        torch.set_num_threads(previous)


@contextmanager
def blas_threads(threads: int | None) -> Iterator[None]:
    """Run the block with ``threads`` BLAS threads for numpy/scipy (``None``: unchanged).

    threadpoolctl's limit is process-wide while the block runs. The loaded libraries are
    scanned once per process (``_controller``): a fresh ``threadpool_limits`` scanned them on
    every entry, 0.8-3 ms, twice per refined clip; entering the cached controller's limit
    takes 0.02 ms.
    """
    if threads is None:
        yield
        return
    with _controller().limit(limits=int(threads), user_api="blas"):
        yield


@lru_cache(maxsize=1)
def _controller() -> ThreadpoolController:
    """The process's thread pools, scanned once (numpy's OpenBLAS is loaded by then)."""
    return ThreadpoolController()


def one_thread():
    """``torch_threads(1)``: for batched small factorisations and single-pose calls."""
    return torch_threads(1)


@contextmanager
def single_threaded() -> Iterator[None]:
    """One torch and one BLAS thread: work made of many small rig batches and products
    (mapping a clip, posing while a browser draws) where threads only contend."""
    with torch_threads(1), blas_threads(1):
        yield
