"""The monitor's ticker: a tick every interval, or sooner when asked to."""

from __future__ import annotations

import threading
import time

import pytest

from worker.ticker import Ticker


def _wait(event: threading.Event, what: str) -> None:
    assert event.wait(10.0), what


def test_a_ticker_ticks_as_soon_as_sooner_says_so_and_only_then() -> None:
    ticks: list[float] = []
    ticked = threading.Event()
    ready = threading.Event()

    def tick() -> None:
        ticks.append(time.monotonic())
        ticked.set()

    def sooner() -> bool:
        # Yes once per set(), on the ticker's thread: the test's thread clearing it
        # after the tick could come later than the next poll on a loaded machine.
        if ready.is_set():
            ready.clear()
            return True
        return False

    ticker = Ticker(tick, 600.0, name="test", sooner=sooner, poll_s=0.05)
    ticker.start()
    try:
        time.sleep(0.5)
        assert ticks == []  # not due, not asked
        ready.set()
        _wait(ticked, "no early tick")
        time.sleep(0.5)
        assert len(ticks) == 1
    finally:
        ticker.stop()


def test_a_failing_sooner_is_logged_and_the_ticker_keeps_its_interval(
    caplog: pytest.LogCaptureFixture,
) -> None:
    ticks: list[float] = []
    twice = threading.Event()

    def tick() -> None:
        ticks.append(time.monotonic())
        if len(ticks) == 2:
            twice.set()

    failing = [True]
    answered = threading.Event()

    def sooner() -> bool:
        if failing[0]:
            raise RuntimeError("shared memory gone")
        answered.set()
        return False

    ticker = Ticker(tick, 0.3, name="test-failing", sooner=sooner, poll_s=0.05)
    caplog.set_level("INFO", logger="worker.ticker")
    ticker.start()
    try:
        _wait(twice, "the ticker stopped ticking")
        failing[0] = False
        _wait(answered, "sooner was not asked again")
    finally:
        ticker.stop()
    assert ticks[1] - ticks[0] >= 0.3 - 0.01
    said = [r.getMessage() for r in caplog.records if r.name == "worker.ticker"]
    # Once an episode (it failed at about 12 polls), not at every poll; then once cleared.
    assert said[0] == (
        "test-failing: could not tell whether to tick early (RuntimeError: shared memory "
        "gone); ticking every 0.3 s"
    ), said
    assert said[1].startswith("test-failing: tells whether to tick early again after"), said
    assert len(said) == 2, said


def test_a_stopped_ticker_stops_while_it_polls() -> None:
    ticker = Ticker(lambda: None, 600.0, name="test-stop", sooner=lambda: False)
    ticker.start()
    ticker.stop(timeout_s=5.0)
    assert not ticker._thread.is_alive()


@pytest.mark.parametrize("poll_s", [0.0, -1.0, float("nan")])
def test_a_poll_that_is_not_positive_is_refused(poll_s: float) -> None:
    with pytest.raises(ValueError, match=f"a ticker needs a poll > 0 s, got {poll_s!r}"):
        Ticker(lambda: None, 1.0, name="test", poll_s=poll_s)
