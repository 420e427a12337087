"""A worker stopped by SIGTERM to its whole process group (a terminal's Ctrl-C, a
supervisor that signals the group) exits: its task process, told twice (by the group's
signal, then by the pool once it said it is exiting), dies only after it let go of the
pool's result queue.

Before, the pool's result thread sent its SIGTERM while the task process still held the
queue's write lock; billiard blocks the signal in the process's main thread only, another
of its threads took it, and the process died holding the lock: the worker hung in "Warm
shutdown" for ever (filesystem broker, idle, by hand: 2 stops of 30 at 2871866, 6 of 30 at
1eccec1; 0 of 30 after).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from types import SimpleNamespace
from typing import TYPE_CHECKING

import billiard
from billiard.pool import DEATH

from worker import process

if TYPE_CHECKING:
    from conftest import Service

#: Far longer than a warm shutdown takes (4-8 s measured on the loaded 2-core machine).
STOP_TIMEOUT_S = 90.0


def test_an_exiting_task_process_is_signalled_only_once_it_let_go_of_the_result_queue() -> None:
    signalled: list[tuple[int, int]] = []
    handlers = {DEATH: lambda pid, code: signalled.append((pid, code))}
    lock = billiard.Lock()
    pool = SimpleNamespace(
        _result_handler=SimpleNamespace(state_handlers=handlers),
        _outqueue=SimpleNamespace(_wlock=lock),
    )
    process._signal_an_exiting_task_process_once_it_let_go_of_the_results(
        sender=SimpleNamespace(pool=SimpleNamespace(_pool=pool))
    )
    lock.acquire()  # the task process, writing its DEATH
    reading = threading.Thread(target=handlers[DEATH], args=(4321, 15))
    reading.start()
    reading.join(0.5)
    held = list(signalled)
    lock.release()
    reading.join(30)
    assert held == [], "signalled while it held the result queue's lock"
    assert signalled == [(4321, 15)]


def test_a_worker_stopped_with_its_process_group_exits(deployment: Service) -> None:
    worker = deployment.start_worker()
    os.killpg(worker.process.pid, signal.SIGTERM)
    deadline = time.monotonic() + STOP_TIMEOUT_S
    try:
        while worker.alive() and time.monotonic() < deadline:
            time.sleep(0.1)
        code = worker.process.poll()
    finally:
        worker.kill()
    assert code == 0, worker.log()
