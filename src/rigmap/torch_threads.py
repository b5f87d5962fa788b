"""How many torch threads a piece of small dense work runs on.

On a busy 2-core machine torch's threads mostly wait for each other on small matrices
and short calls (measured on this project's machine: a 218² batched Cholesky 0.6 ms on
one thread and 8 ms on two; a 150² Cholesky 0.13 ms and 22 ms; a single-pose rig call
about halved), so refinement, the GPLVM fit and interactive posing pin one thread while
they run, and the networks take their thread count from config.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import torch


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


def one_thread():
    """``torch_threads(1)``: for batched small factorisations and single-pose calls."""
    return torch_threads(1)
