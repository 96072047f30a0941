"""Task runners by name: threads on one machine (default), Dask for scaling out."""

from __future__ import annotations

from multithumbs.errors import InputError

RUNNERS = ("threads", "dask")


def make_task_runner(name: str = "threads", workers: int = 2, address: str | None = None):
    """A Prefect task runner.

    Args:
        name: ``threads`` (a thread pool in the flow's process) or ``dask`` (prefect-dask: a local cluster of
            ``workers`` single-threaded processes, or the existing cluster at ``address``).
        workers: parallel tasks.
        address: scheduler address of a running Dask cluster (``tcp://host:8786``), ``dask`` only.
    """
    if workers < 1:
        raise InputError(f"workers: must be at least 1, got {workers}")
    if name == "threads":
        from prefect.task_runners import ThreadPoolTaskRunner

        return ThreadPoolTaskRunner(max_workers=workers)
    if name == "dask":
        try:
            from prefect_dask import DaskTaskRunner
        except ImportError as exc:
            raise InputError("task runner dask: prefect-dask is not installed (pip install 'multithumbs[dask]')") from exc
        if address:
            return DaskTaskRunner(address=address)
        # One thread per worker process (each task already uses torch's threads), no worker memory limit.
        return DaskTaskRunner(cluster_kwargs={"n_workers": workers, "threads_per_worker": 1, "processes": True,
                                              "memory_limit": 0, "dashboard_address": None})
    raise InputError(f"task runner {name!r}: unknown; choose from {', '.join(RUNNERS)}")
