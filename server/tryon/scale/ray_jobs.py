"""Ray as the engine of the batch work: connect (a local Ray, or a running cluster), run plain functions
as tasks, hand results back as they finish.

Ray is optional (``pip install '.[scale]'``); without it :func:`connect` raises :class:`RayUnavailable`
with the install command. Tasks are retried by Ray when their worker dies (``TASK_RETRIES``); an exception
raised by the function itself is not retried but handed back (its ``cause``, not Ray's wrapper text).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from typing import Any

# Times Ray runs a task again when its worker process dies (not when the function raises).
TASK_RETRIES = 3


class RayUnavailable(RuntimeError):
    """Ray cannot be used here: not installed, or the cluster cannot be reached."""


def connect(address: str | None, num_cpus: int | None = None) -> bool:
    """Join the Ray cluster at ``address`` (``"auto"`` or ``host:port``), or start a local one (None) with
    ``num_cpus`` worker slots (default: every core). Returns whether this call started Ray (the caller then
    stops it with :func:`disconnect`). The kernels' cache directory goes to the workers in their
    environment, so they load the kernels the driver compiled."""
    try:
        import ray
    except ImportError:
        raise RayUnavailable("Ray is not installed: pip install '.[scale]' (or without --ray, on this machine)") \
            from None
    if ray.is_initialized():
        return False
    env = {k: os.environ[k] for k in ("NUMBA_CACHE_DIR",) if k in os.environ}
    # a task holds one CPU: a large garment's two-thread passes (sim/blocks.py) would oversubscribe the node
    env["NUMBA_NUM_THREADS"] = "1"
    try:
        ray.init(address=address, num_cpus=None if address else (num_cpus or os.cpu_count()),
                 include_dashboard=False, log_to_driver=False, logging_level="ERROR",
                 runtime_env={"env_vars": env})
    except (ConnectionError, ValueError, RuntimeError) as exc:
        where = address or "a local Ray"
        raise RayUnavailable(f"cannot start or reach {where}: {str(exc).splitlines()[0]}") from None
    return True


def disconnect() -> None:
    import ray

    ray.shutdown()


def run_tasks(fn: Callable[..., Any], arguments: Iterable[tuple], shared: tuple = ()) -> Iterator[tuple[int, Any]]:
    """Run ``fn(*args, *shared)`` as one Ray task per element of ``arguments``; yield ``(index, result)`` in
    the order they finish, ``result`` being the exception when ``fn`` raised. ``shared`` is put in Ray's
    object store once and passed to every task (large read-only data: prepared models)."""
    import ray

    task = ray.remote(max_retries=TASK_RETRIES)(fn)
    shared_refs = [ray.put(x) for x in shared]
    refs = {task.remote(*args, *shared_refs): i for i, args in enumerate(arguments)}
    pending = list(refs)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        for ref in done:
            try:
                yield refs[ref], ray.get(ref)
            except ray.exceptions.RayTaskError as exc:
                yield refs[ref], exc.cause if isinstance(exc.cause, BaseException) else exc
            except ray.exceptions.RayError as exc:  # the worker died past its retries, the node left...
                yield refs[ref], exc
