"""Simulated trials on Dask distributed: a ``LocalCluster`` here, or a lab's scheduler.

One code path whatever the size: :func:`dask_client` opens a ``LocalCluster`` of ``workers``
processes with one thread each (torch single-threaded in every worker: parallelism comes from the
processes), or connects to ``scheduler`` (``tcp://host:8786``, a lab's ``dask scheduler``; its
workers need this package installed and should run ``--nthreads 1``). :func:`run_tasks` maps a
function over task arguments and hands each result back as it completes, with a progress bar.
Every task is seeded by its arguments alone, so results do not depend on the workers.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from distributed import Client, LocalCluster, as_completed
from tqdm import tqdm

#: Thread counts of the numerical libraries in each local worker process.
_SINGLE_THREADED = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                    "OPENBLAS_NUM_THREADS": "1"}


@contextmanager
def dask_client(scheduler: str | None = None, workers: int = 1) -> Iterator[Client]:
    """A client on ``scheduler``, or on a new ``LocalCluster`` of ``workers`` processes."""
    logging.getLogger("distributed").setLevel(logging.WARNING)  # no per-run INFO chatter
    if scheduler is not None:
        with Client(scheduler) as client:
            yield client
        return
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=logging.ERROR,
                      env=_SINGLE_THREADED) as cluster, Client(cluster) as client:
        yield client


def single_threaded_call(function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)`` with torch single-threaded (on any worker, also a lab's)."""
    import torch

    torch.set_num_threads(1)
    return function(*args)


def run_tasks(client: Client, function: Callable[..., Any], tasks: Iterable[tuple[Any, ...]],
              on_done: Callable[[Any], None], *, total: int, initial: int = 0, desc: str = "",
              progress: bool = True) -> None:
    """Run ``function(*task)`` for every task on the cluster; ``on_done(result)`` in the caller's
    process as each finishes (in completion order). The bar counts ``initial`` done of ``total``."""
    futures = [client.submit(single_threaded_call, function, *task, pure=False)
               for task in tasks]
    with tqdm(total=total, initial=initial, desc=desc, unit="trial", disable=not progress,
              mininterval=2.0, dynamic_ncols=True) as bar:
        for future in as_completed(futures):
            on_done(future.result())
            bar.update()
            future.release()
