"""Two threads for one try-on only while no other program needs the cores.

A large garment's passes run on two threads (``sim.blocks``) when the pool gives a try-on both cores. On a
machine shared with other programs that is a gamble: every pass ends at a barrier where one thread waits for
the other, and a thread that shares its core with another program waits for its turn on that core. Measured
on the 2-core machine with a real 20,579-spring dress (``dress-straps-diffavatar``, a mid-size woman, 96
steps; drapes of one thread and of two in turn, with 0, 1 and 2 busy loops of another process):

| other programs busy | one thread, s | two threads, s |
|---|---|---|
| none | 0.63 | 0.53 |
| one | 0.63 | 1.34-1.93 |
| two | 0.93-1.06 | 1.33-4.20 |

Timing a few steps on two threads to find out costs too much where it matters (single steps of 100-500 ms
with two other programs busy), so a try-on looks at the machine instead: the CPU time the whole machine
spent (``/proc/stat``) minus this process's own (``time.process_time``, every try-on of the pool included)
is what other programs used. A try-on uses its allowed threads only while the others leave that many cores
free, else one. The results are the same on one thread or two (``sim.blocks``): only the time changes.
"""

from __future__ import annotations

import os
import time

# Seconds over which the others' CPU use is measured before the choice is made again (the kernel's counters
# move in 10 ms ticks: 0.2 s gives the others' cores to +-0.05).
WINDOW_S = 0.2
# Cores the other programs may keep busy, on average over the window, for a try-on to use more than one
# thread: a core used more than half by others makes a thread of ours wait at every barrier.
OTHERS_MAX = 0.5
# Seconds a window's figure is trusted by a try-on that starts after it.
FRESH_S = 2.0


def _machine_busy_seconds() -> float | None:
    """CPU seconds the machine spent busy since boot (every core; stolen time counts as busy: a hypervisor
    that takes the core away is another program too), or None where ``/proc/stat`` is not readable."""
    try:
        with open("/proc/stat", "rb") as f:
            fields = f.readline().split()[1:9]
    except OSError:
        return None
    ticks = [int(v) for v in fields]
    idle = ticks[3] + ticks[4]  # idle, iowait
    return (sum(ticks) - idle) / os.sysconf("SC_CLK_TCK")


class ThreadChoice:
    """How many threads a running try-on uses for its next step: ``threads(allowed)``, called once per step
    with the threads the pool allows now. ``allowed`` while the other programs kept at most ``OTHERS_MAX`` of
    a core busy over the last ``WINDOW_S`` (measured again every window), else one. A try-on starts from
    the last window any try-on of this process measured if it is at most ``FRESH_S`` old, else on one thread
    until its own first window is measured (a first window on two threads on a busy machine could cost
    seconds; on one thread on an idle one, ~20 % of 0.2 s)."""

    def __init__(self) -> None:
        self._mark: tuple[float, float, float] | None = None  # (wall, machine busy, own CPU) at the window start
        when, others = _LAST
        self.others = others if time.perf_counter() - when <= FRESH_S else float("inf")

    def threads(self, allowed: int) -> int:
        if allowed < 2:
            return 1
        now = time.perf_counter()
        if self._mark is None or now - self._mark[0] >= WINDOW_S:
            busy, own = _machine_busy_seconds(), time.process_time()
            if busy is None:
                return allowed
            if self._mark is not None:
                self.others = max(0.0, (busy - self._mark[1]) - (own - self._mark[2])) / (now - self._mark[0])
                _LAST[:] = [now, self.others]
            self._mark = (now, busy, own)
        return allowed if self.others <= OTHERS_MAX else 1


# (when, cores the others used) of the last window measured by any try-on of this process
_LAST: list[float] = [float("-inf"), 0.0]
