"""Independent tasks, in this process or on a Dask cluster.

The loop has three kinds of work made of independent tasks: the candidate
fits of a diagnosis, the chains of an update, and the scenarios of a sweep.
Each takes a *mapper*, ``mapper(function, items, **shared) -> list``, that
runs ``function(item, **shared)`` for every item and returns the results in
the order of the items. :func:`mapper` makes one from

* ``None``: in this process, one item after the other;
* a :class:`distributed.Client`: one Dask task per item. The ``shared``
  arguments are scattered to the workers once (a Gibbs problem with its
  precomputed matrices is not sent with every chain), and a task's error is
  raised here with its own type and message;
* any callable with the mapper's signature.

:func:`dask_client` opens the client the command line uses: ``"local"`` (a
local cluster of worker processes, one thread each: the default of
``--scheduler``), a scheduler address such as ``tcp://10.0.0.5:8786`` (an
existing cluster; its workers need twin installed, and files they write go to
*their* file system), or ``"sync"`` (no Dask: in this process).

Results do not depend on where the tasks ran: every random stream is seeded
before the tasks are made.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from twin.progress import bar

from twin.errors import TwinError

log = logging.getLogger(__name__)

T = TypeVar("T")
R = TypeVar("R")
Mapper = Callable[..., list]

#: ``--scheduler`` values that do not name an address.
LOCAL, SYNC = "local", "sync"


def one_blas_thread(function: Callable[..., R]) -> Callable[..., R]:
    """Run ``function`` with one BLAS thread (threadpoolctl).

    The loop's work is many small dense problems (116-DOF factorisations,
    232-state eigen-solutions, the Gibbs sweep's batched algebra). On them a
    second OpenBLAS thread costs more in hand-over than it gains: a diagnosis
    of the hydro unit took 29.6 s with the two threads of a 2-core machine
    and 9.2 s with one. Parallel work goes to tasks instead (:func:`mapper`).

    Examples
    --------
    >>> import numpy as np
    >>> one_blas_thread(np.linalg.det)(np.eye(3))
    np.float64(1.0)
    """
    import functools

    @functools.wraps(function)
    def run(*args: Any, **kwargs: Any) -> R:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return function(*args, **kwargs)

    return run


def blas_threads() -> int:
    """The threads the loaded BLAS libraries use now (the most of them; 1 with none loaded).

    Examples
    --------
    >>> one_blas_thread(blas_threads)()
    1
    """
    from threadpoolctl import threadpool_info

    return max((p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"), default=1)


def in_process(function: Callable[..., R], items: Sequence[T], **shared: Any) -> list[R]:
    """Run ``function(item, **shared)`` for each item here, in order.

    Examples
    --------
    >>> in_process(pow, [1, 2, 3], exp=2)
    [1, 4, 9]
    """
    return [function(item, **shared) for item in items]


def dask_mapper(client: Any, *, progress: bool = False, desc: str = "tasks") -> Mapper:
    """A mapper that runs one Dask task per item on ``client``.

    Parameters
    ----------
    client : distributed.Client
    progress : bool
        A progress bar over the finished tasks.
    desc : str
        Label of the progress bar.
    """
    from distributed import as_completed

    def run(function: Callable[..., R], items: Sequence[T], **shared: Any) -> list[R]:
        items = list(items)
        if not items:
            return []
        # containers (a dict of start values, a tuple of labels) are small, and scatter would take a dict's keys
        # for names: they go with the tasks; models and updating problems are scattered once
        scattered = {
            k: v
            if isinstance(v, (dict, list, tuple, set, str, int, float, type(None)))
            else client.scatter(v, broadcast=True, hash=False)
            for k, v in shared.items()
        }
        futures = client.map(function, items, pure=False, **scattered)
        with bar(total=len(futures), desc=desc, progress=progress, leave=False) as finished:
            for _ in as_completed(futures):
                finished.update()
        return client.gather(futures)

    return run


def mapper(tasks: Any = None, *, progress: bool = False, desc: str = "tasks") -> Mapper:
    """The mapper for ``tasks``: None (in process), a ``distributed.Client``, or a mapper itself.

    Examples
    --------
    >>> mapper(None)(abs, [-1, 2])
    [1, 2]
    """
    if tasks is None:
        if not progress:
            return in_process

        def in_process_with_bar(function: Callable[..., R], items: Sequence[T], **shared: Any) -> list[R]:
            return [function(item, **shared) for item in bar(list(items), desc=desc, progress=True, leave=False)]

        return in_process_with_bar
    if _is_client(tasks):
        return dask_mapper(tasks, progress=progress, desc=desc)
    if callable(tasks):
        return tasks
    raise TwinError(f"tasks must be None, a distributed.Client or a mapper function, got {type(tasks).__name__}")


def _is_client(obj: Any) -> bool:
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - distributed is a dependency
        return False
    return isinstance(obj, Client)


@contextmanager
def _workers_ignore_ctrl_c() -> Iterator[None]:
    """Start worker processes with Ctrl-C (SIGINT) ignored, this process's handler kept.

    A terminal sends Ctrl-C to every process of the command, and each worker then died with a page of
    KeyboardInterrupt tracebacks after the command's one-line message. Spawned workers inherit an ignored
    signal, so only this process hears it and closes them (:func:`dask_client`'s ``finally``).
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():  # signal handlers belong to the main thread
        yield
        return
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


@contextmanager
def dask_client(
    scheduler: str | None = LOCAL, *, n_workers: int | None = None, timeout_s: float = 10.0
) -> Iterator[Any]:
    """A Dask client for ``scheduler``, closed on exit (``None`` for ``"sync"``).

    Parameters
    ----------
    scheduler : str or None
        ``"local"``: start a local cluster of ``n_workers`` worker processes
        (default: one per core), one thread each, closed on exit;
        ``"sync"`` or None: no Dask, the tasks run in this process;
        anything else: the address of a running scheduler (``tcp://host:8786``).
    n_workers : int, optional
        Workers of the local cluster.
    timeout_s : float
        How long to try to reach a scheduler address [s].

    Yields
    ------
    distributed.Client or None
        Pass it as ``tasks=`` to :func:`twin.loop.diagnose.diagnose`,
        :func:`twin.update.update` or :func:`twin.harness.sweep.sweep`.

    Examples
    --------
    >>> with dask_client("sync") as client:
    ...     mapper(client)(abs, [-3])
    [3]
    """
    if scheduler is None or scheduler == SYNC:
        yield None
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError as err:  # pragma: no cover - distributed is a dependency
        raise TwinError(f"--scheduler {scheduler} needs dask.distributed: pip install 'dask[distributed]'") from err
    if scheduler == LOCAL:
        workers = (os.cpu_count() or 1) if n_workers is None else int(n_workers)
        if workers < 1:
            raise TwinError(f"a local cluster needs at least one worker, got {workers}")
        import dask

        # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers, which makes glibc hand every freed
        # temporary back to the system: the Gibbs sweeps, made of many medium-sized temporaries, run 1.4x
        # slower under it (measured). The local workers keep glibc's default and one BLAS thread each.
        # Dask's statistical profiler samples each worker's running task every 10 ms and takes the GIL to
        # do it: with it, 20 records' extractions on two workers ran at 29.0 records a minute against 32.9
        # without (80 others in a track: 28.3 against 28.9). The local workers run without it (their
        # dashboard's profile page stays empty).
        environ = {
            k: v
            for k, v in dask.config.get("distributed.nanny.pre-spawn-environ", {}).items()
            if k != "MALLOC_TRIM_THRESHOLD_"
        }
        settings = {"distributed.nanny.pre-spawn-environ": environ, "distributed.worker.profile.enabled": False}
        from twin.progress import stage

        with dask.config.set(settings), stage(f"start {workers} Dask workers"), _workers_ignore_ctrl_c():
            cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=":0",
                silence_logs=logging.ERROR,
            )
        client = Client(cluster)
        log.info("local Dask cluster at %s, %d workers", cluster.scheduler_address, workers)
        try:
            yield client
        finally:
            # a worker still busy with a cancelled task (an error, Ctrl-C) is killed on close; the nanny
            # says so at WARNING, which reads as a failure of a run that went well: kept to its errors
            nanny = logging.getLogger("distributed.nanny")
            level = nanny.level
            nanny.setLevel(logging.ERROR)
            try:
                client.close()
                cluster.close()
            finally:
                nanny.setLevel(level)
        return
    try:
        client = Client(scheduler, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError, ValueError) as err:
        raise TwinError(f"cannot reach the Dask scheduler at '{scheduler}': {err}") from err
    log.info("Dask scheduler at %s", scheduler)
    try:
        yield client
    finally:
        client.close()
