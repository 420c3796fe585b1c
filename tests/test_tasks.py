"""Independent tasks here or on a local Dask cluster: same results, errors raised here, shared data sent once."""

import numpy as np
import pytest

from twin.errors import TwinError
from twin.tasks import dask_client, in_process, mapper


def _scaled(x, factor):
    return x * factor


def _fails(x):
    raise TwinError(f"task {x} refuses")


def _worker_pid(_x, payload):
    import os
    import time

    time.sleep(0.2)  # long enough that both workers take some
    return os.getpid(), float(payload.sum())


def test_in_process_keeps_the_order_and_passes_shared_arguments():
    assert in_process(_scaled, [3, 1, 2], factor=10) == [30, 10, 20]
    assert mapper(None) is in_process
    assert mapper(in_process) is in_process


def test_mapper_refuses_what_is_neither_client_nor_function():
    with pytest.raises(TwinError, match="tasks must be None, a distributed.Client or a mapper function, got int"):
        mapper(4)


def test_sync_scheduler_is_no_dask():
    with dask_client("sync") as client:
        assert client is None


def test_unreachable_scheduler_is_a_clear_error():
    with pytest.raises(TwinError, match="cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"):
        with dask_client("tcp://127.0.0.1:9", timeout_s=1):
            pass


def test_local_cluster_runs_tasks_on_its_workers_in_order(dask_local):
    run = mapper(dask_local)
    payload = np.ones(200_000)  # scattered once, not sent with each task
    results = run(_worker_pid, list(range(8)), payload=payload)
    assert [r[1] for r in results] == [200_000.0] * 8
    assert len({r[0] for r in results}) == 2  # both worker processes took tasks
    assert run(_scaled, [1, 2, 3], factor=2) == [2, 4, 6]
    assert run(_scaled, [], factor=2) == []


def test_a_failing_task_raises_its_own_error_here(dask_local):
    with pytest.raises(TwinError, match="task 2 refuses"):
        mapper(dask_local)(_fails, [2])


def _sigint_disposition(_):
    import signal

    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN


def test_local_workers_leave_ctrl_c_to_this_process(dask_local):
    """A terminal's Ctrl-C reaches every process of the command: the workers ignore it (they printed a page of
    KeyboardInterrupt tracebacks each), and this process keeps its own handler to close them."""
    import signal

    assert mapper(dask_local)(_sigint_disposition, [0, 1]) == [True, True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
