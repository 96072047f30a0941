"""One thread count for every computation whose result depends on it (the store's keys must mean bytes).

CPU torch splits reductions and matrix products across its intra-op threads, and the split changes the
rounding: the float32 body model's vertices differ by ~1e-7 between one and two threads, and the view
registration and alignment carry such differences to 1e-4 of the ATE (tests/flows/test_resume.py failed so).
A content-addressed store needs the same inputs to give the same bytes, so every stage computes with the
same count, set in the computing thread itself.

Why not a scoped setting (set, compute, restore): torch's count is process-global (MKL's) and per thread
(OpenMP's), and a thread's first parallel op copies the process-wide value. With tasks in threads, one
task's scoped ``set 1 ... restore`` was what another task's new thread copied, and two overlapping scopes
restored each other's values: the process was left at one thread or two depending on timing.
numpy's BLAS (OpenBLAS) gave identical results at one and two threads on the method's inputs; it is set
as well when ``threadpoolctl`` is installed.
"""

from __future__ import annotations

import torch

THREADS = 1
"""Intra-op threads of every stage: the method's loops are bound by op count (benchmarks/method.py: one
thread 19.0 s against two 21.4 s), and one thread has no split to vary."""


def fix_threads(count: int = THREADS) -> None:
    """Compute with ``count`` torch intra-op threads in the calling thread and the process, for good.

    Call it in the thread that computes (a task runner's worker), before computing: a thread that has
    already run a parallel op keeps its own count otherwise. Not restored afterwards, on purpose (module
    docstring). Also turns on torch's deterministic algorithms (CPU: the few ops with a non-deterministic
    kernel raise instead of varying) and, with ``threadpoolctl`` installed, sets BLAS's threads too.
    """
    if count <= 0:
        raise ValueError(f"thread count {count}: must be positive")
    torch.set_num_threads(count)
    torch.use_deterministic_algorithms(True)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    threadpool_limits(count)
