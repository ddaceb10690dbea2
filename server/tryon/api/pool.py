"""The bounded simulation pool, the per-simulation wall-clock limit, and the try-on result cache.

Simulations run in a fixed set of worker threads (``settings.sim_workers``): the numba kernels are
compiled with ``nogil=True``, so threads simulate in parallel while the event loop keeps answering.
At most ``sim_workers + sim_queue`` simulations are admitted at once (running or waiting for a worker);
one more is refused at once with :class:`PoolFull` (REST: 503 with ``Retry-After``; WebSocket: close
code 1013 "try again later"), never left hanging.

A :class:`RunGuard` wraps a drape's ``on_frame`` callback: it returns False (stop) as soon as the client
is gone or the simulation is past its wall-clock limit, and records which of the two stopped it.

A large garment's spring passes run on two threads (``sim.blocks``, the same numbers on one or two): a
try-on running alone may use the machine's cores, two at once one each (set when a job starts and again at
every frame, so a running try-on gives a core back when another starts): the try-ons per minute with two
at once stay those of two single-threaded runs. A try-on allowed two threads uses one while another
program keeps a core busy (``threads.ThreadChoice``): two threads are then slower than one.

:class:`ResultCache` keeps the last ``settings.result_cache_size`` finished try-ons in memory (LRU),
keyed by :func:`request_key` (:func:`tryon_key` for a request): the canonical JSON of garment id,
measurements, pose and settings. Only runs that ended by themselves (rest or step limit) are kept.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tryon.api.deps import app_state
from tryon.api.threads import ThreadChoice
from tryon.sim.blocks import machine_threads, use_threads

# Seconds a refused client is told to wait (Retry-After): about one typical drape on this hardware.
RETRY_AFTER_S = 5


class PoolFull(RuntimeError):
    """Every worker is busy and every waiting slot is taken: come back in ``retry_after_s`` seconds."""

    def __init__(self, capacity: int, retry_after_s: int = RETRY_AFTER_S):
        super().__init__(
            f"the server is busy: {capacity} try-ons are already running or waiting; "
            f"please try again in {retry_after_s} s"
        )
        self.capacity = capacity
        self.retry_after_s = retry_after_s


class RunCancelled(Exception):
    """Raised by :class:`RunGuard` inside a drape whose client is gone: unwinds the worker at once (no
    final polish, no metrics), since nobody will read the result."""


class SimPool:
    """A thread pool that admits at most ``workers + queue`` jobs and refuses the next one at once.

    workers: simulations running at the same time (threads).
    queue: admitted simulations that may wait for a free worker.
    wall_limit_s: wall-clock seconds one simulation may run (enforced by :class:`RunGuard`).
    """

    def __init__(self, workers: int, queue: int, wall_limit_s: float):
        self.workers = int(workers)
        self.queue = int(queue)
        self.capacity = self.workers + self.queue
        self.wall_limit_s = float(wall_limit_s)
        self._executor = ThreadPoolExecutor(max_workers=self.workers, thread_name_prefix="tryon-sim")
        self._lock = threading.Lock()
        self._admitted = 0  # running + waiting
        self._running = 0
        self._counts = {"submitted": 0, "refused": 0, "completed": 0, "failed": 0, "cancelled": 0}

    # -- admission -----------------------------------------------------------------------------
    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Future:
        """Run ``fn(*args, **kwargs)`` on a worker; raise :class:`PoolFull` at once when full."""
        with self._lock:
            if self._admitted >= self.capacity:
                self._counts["refused"] += 1
                raise PoolFull(self.capacity)
            self._admitted += 1
            self._counts["submitted"] += 1

        def job() -> Any:
            with self._lock:
                self._running += 1
            use_threads(self.thread_share())
            try:
                return fn(*args, **kwargs)
            finally:
                with self._lock:
                    self._running -= 1

        future = self._executor.submit(job)
        future.add_done_callback(self._release)  # also runs when a waiting job is cancelled
        return future

    async def run(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Await ``fn(*args, **kwargs)`` run on a worker (raises :class:`PoolFull` when full)."""
        return await asyncio.wrap_future(self.submit(fn, *args, **kwargs))

    def _release(self, future: Future) -> None:
        with self._lock:
            self._admitted -= 1
            if future.cancelled() or isinstance(future.exception(), RunCancelled):
                self._counts["cancelled"] += 1
            elif future.exception() is not None:
                self._counts["failed"] += 1
            else:
                self._counts["completed"] += 1

    def guard(self, cancelled: threading.Event | None = None,
              on_frame: Callable[[int, np.ndarray], Any] | None = None) -> "RunGuard":
        """A :class:`RunGuard` with this pool's wall-clock limit and thread share."""
        return RunGuard(self.wall_limit_s, cancelled=cancelled, on_frame=on_frame, threads=self.thread_share)

    def thread_share(self) -> int:
        """Threads a running try-on may use now: the machine's cores shared among the running ones."""
        with self._lock:
            running = max(1, self._running)
        return max(1, machine_threads() // running)

    # -- state ---------------------------------------------------------------------------------
    def stats(self) -> dict:
        """Counters for ``/api/health``: running, waiting, capacity and totals since start."""
        with self._lock:
            return {
                "workers": self.workers,
                "queue": self.queue,
                "capacity": self.capacity,
                "running": self._running,
                "waiting": self._admitted - self._running,
                "wall_limit_s": self.wall_limit_s,
                **self._counts,
            }

    def shutdown(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)


class RunGuard:
    """``on_frame`` for ``drape``: stops the run when the client is gone or time is up.

    wall_limit_s: seconds from :meth:`start` (or the first frame) after which every call returns False
        (the drape ends normally and its result says it was cut short).
    cancelled: set by the caller (e.g. the WebSocket went away): the next call raises
        :class:`RunCancelled`, so the worker is free at once.
    on_frame: an optional inner callback ``(step, coarse (k, 3)) -> bool | None``; False also stops.
    threads: an optional ``() -> int``, the threads the run may use now (``SimPool.thread_share``); at every
    frame the run uses that many, or one while other programs keep a core busy (``ThreadChoice``).
    After the run, ``stopped_by`` is None (ran to rest or to its step limit), ``"wall_limit"``,
    ``"cancelled"`` or ``"callback"``.
    """

    def __init__(self, wall_limit_s: float, cancelled: threading.Event | None = None,
                 on_frame: Callable[[int, np.ndarray], Any] | None = None,
                 threads: Callable[[], int] | None = None):
        self.wall_limit_s = float(wall_limit_s)
        self.threads = threads
        self.cancelled = cancelled or threading.Event()
        self.on_frame = on_frame
        self.started: float | None = None
        self.stopped_by: str | None = None
        self.frames = 0
        self.choice = ThreadChoice()

    def start(self) -> "RunGuard":
        if self.started is None:
            self.started = time.monotonic()
        return self

    @property
    def elapsed_s(self) -> float:
        return 0.0 if self.started is None else time.monotonic() - self.started

    def __call__(self, step: int, coarse: np.ndarray) -> bool:
        self.start()
        self.frames += 1
        if self.cancelled.is_set():
            self.stopped_by = "cancelled"
            raise RunCancelled("the client went away")
        if self.elapsed_s > self.wall_limit_s:
            self.stopped_by = "wall_limit"
            return False
        if self.threads is not None:
            use_threads(self.choice.threads(self.threads()))
        if self.on_frame is not None and self.on_frame(step, coarse) is False:
            self.stopped_by = "callback"
            return False
        return True


# -- result cache ------------------------------------------------------------------------------
def canonical_json(payload: Any) -> str:
    """JSON with sorted keys, no spaces and floats as Python repr: equal requests give equal text."""
    return json.dumps(payload, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def request_key(garment_id: str, measurements: dict, pose: dict, settings: dict) -> str:
    """Cache key (sha256 hex) of one try-on: garment id + measurements + pose + settings.

    Pass the validated request's parts as plain dicts (``model_dump(mode="json")``), so defaults are
    filled in and ``{"height": 170}`` and ``{"height": 170.0}`` give the same key.
    """
    def floats(d: dict) -> dict:
        return {k: (float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v)
                for k, v in (d or {}).items()}

    text = canonical_json({"garment_id": garment_id, "measurements": floats(measurements),
                           "pose": floats(pose), "settings": floats(settings)})
    return hashlib.sha256(text.encode()).hexdigest()


# Request fields that change how a result is shown, not the result: left out of the cache key.
DISPLAY_FIELDS = frozenset({"fps", "encoding", "live"})


def tryon_key(request: Any, catalogue: Any = None) -> str:
    """:func:`request_key` of a validated try-on request (pydantic; display-only fields excluded):
    garment id, measurements, pose, and the settings with every other field. With ``catalogue``, also each
    garment's cloth (fabric and density, which a PATCH may change under the same id: another drape)."""
    data = request.model_dump(mode="json", exclude=set(DISPLAY_FIELDS))
    settings = {**(data.pop("settings", None) or {}), **{k: v for k, v in data.items()
                                                        if k not in ("garment_id", "measurements", "pose")}}
    if catalogue is not None:
        metas = [catalogue.get(gid) for gid in request.ids]
        settings["cloth"] = [None if m is None else f"{m.fabric}:{m.density!r}" for m in metas]
    return request_key(data["garment_id"], data.get("measurements") or {}, data.get("pose") or {}, settings)


@dataclass
class CachedTryOn:
    """One finished try-on, as kept in memory: one entry whichever way it was asked for (``POST /api/tryon``
    or ``WS /ws/tryon``), so either answers the other's request.

    result: the simulation's ``TryOnResult`` (final full-mesh vertices (n, 3), faces, strain (n,), metrics).
    body: the body it was draped on, as the WebSocket's init message shows it: ``{"vertices": (b, 3) m,
        "faces": (g, 3) int32, "achieved": {measurement: cm}}``; None only in tests of the cache itself.
    settings: the ``SimSettings`` it ran with.
    extra: what a writer derived from it and keeps to replay it faster (the WebSocket's serialised init
        message, ``init_base``, and the body's bounding box (2, 3), ``body_box``).
    created: ``time.time()`` when it finished.
    """

    result: Any
    body: dict | None = None
    settings: Any = None
    extra: dict = field(default_factory=dict)
    created: float = field(default_factory=time.time)


class ResultCache:
    """A thread-safe LRU of at most ``maxsize`` :class:`CachedTryOn` (0 disables caching)."""

    def __init__(self, maxsize: int):
        self.maxsize = int(maxsize)
        self._items: OrderedDict[str, CachedTryOn] = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def get(self, key: str) -> CachedTryOn | None:
        with self._lock:
            item = self._items.get(key)
            if item is None:
                self.misses += 1
                return None
            self._items.move_to_end(key)
            self.hits += 1
            return item

    def put(self, key: str, item: CachedTryOn) -> None:
        if self.maxsize <= 0:
            return
        with self._lock:
            self._items[key] = item
            self._items.move_to_end(key)
            while len(self._items) > self.maxsize:
                self._items.popitem(last=False)

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def stats(self) -> dict:
        with self._lock:
            return {"entries": len(self._items), "maxsize": self.maxsize, "hits": self.hits,
                    "misses": self.misses}


# -- the app's pool ----------------------------------------------------------------------------
def get_pool(app: Any) -> SimPool:
    """The app's :class:`SimPool`, created on first use from ``app.state.settings``."""
    s = app.state.settings
    return app_state(app, "sim_pool", lambda: SimPool(s.sim_workers, s.sim_queue, s.sim_wall_limit_s))


def get_result_cache(app: Any) -> ResultCache:
    """The app's :class:`ResultCache`, created on first use (``settings.result_cache_size`` entries)."""
    return app_state(app, "result_cache", lambda: ResultCache(app.state.settings.result_cache_size))


def busy_response_headers(error: PoolFull) -> dict[str, str]:
    """Headers for the REST 503 answer to :class:`PoolFull`."""
    return {"Retry-After": str(int(math.ceil(error.retry_after_s)))}
