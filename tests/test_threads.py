"""A try-on allowed two threads uses one while another program keeps a core busy (``api.threads``)."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from tryon.api import threads
from tryon.api.pool import RunGuard
from tryon.api.threads import OTHERS_MAX, WINDOW_S, ThreadChoice


class FakeMachine:
    """The machine's busy CPU seconds and this process's, on a clock the test moves."""

    def __init__(self, monkeypatch):
        self.wall = 100.0
        self.busy = 0.0
        self.own = 0.0
        monkeypatch.setattr(threads, "_machine_busy_seconds", lambda: self.busy)
        monkeypatch.setattr(threads.time, "perf_counter", lambda: self.wall)
        monkeypatch.setattr(threads.time, "process_time", lambda: self.own)
        monkeypatch.setattr(threads, "_LAST", [float("-inf"), 0.0])

    def run(self, seconds: float, ours: float, others: float) -> None:
        """``seconds`` of wall time with ``ours`` and ``others`` cores busy."""
        self.wall += seconds
        self.own += ours * seconds
        self.busy += (ours + others) * seconds


def test_two_threads_only_while_the_others_leave_a_core_free(monkeypatch):
    m = FakeMachine(monkeypatch)
    choice = ThreadChoice()
    assert choice.threads(2) == 1  # nothing measured yet: one thread for the first window
    m.run(WINDOW_S, ours=1.0, others=0.1)
    assert choice.threads(2) == 2 and choice.others == pytest.approx(0.1)
    m.run(WINDOW_S / 2, ours=2.0, others=0.0)
    assert choice.threads(2) == 2  # within the window: the last figure holds
    m.run(WINDOW_S / 2 + 0.01, ours=2.0, others=2.0)  # another program starts
    assert choice.threads(2) == 1 and choice.others == pytest.approx(1.0, abs=0.1)
    assert choice.threads(1) == 1  # the pool allows one: one, whatever the load
    m.run(WINDOW_S, ours=1.0, others=OTHERS_MAX)
    assert choice.threads(2) == 2
    # a try-on that starts now takes the last window's figure; one started later than FRESH_S does not
    assert ThreadChoice().threads(2) == 2
    m.run(threads.FRESH_S + 0.1, ours=0.0, others=0.0)
    assert ThreadChoice().threads(2) == 1


def test_a_run_guard_holds_a_try_on_to_one_thread_on_a_busy_machine(monkeypatch):
    m = FakeMachine(monkeypatch)
    used = []
    monkeypatch.setattr("tryon.api.pool.use_threads", used.append)
    guard = RunGuard(10.0, threads=lambda: 2)
    for _ in range(4):
        guard(1, None)
        m.run(WINDOW_S, ours=1.0, others=0.0)
    for _ in range(4):
        guard(1, None)
        m.run(WINDOW_S, ours=1.0, others=1.0)
    assert used == [1, 2, 2, 2, 2, 1, 1, 1]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/stat")
def test_another_busy_program_is_seen():
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.2)
        choice = ThreadChoice()
        choice.threads(2)
        time.sleep(3 * WINDOW_S)
        assert choice.threads(2) == 1 and choice.others >= 0.7, choice.others
    finally:
        busy.kill()
        busy.wait()
