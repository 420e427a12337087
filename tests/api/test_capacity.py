"""The compute gate's refusal past its queue, in words that agree with the count."""

from __future__ import annotations

import anyio
import pytest

from app.capacity import ComputeGate, Overloaded


@pytest.mark.parametrize(
    ("queue", "said"), [(1, "1 request already waits"), (2, "2 requests already wait")]
)
def test_the_refusal_counts_the_waiting_requests_in_agreement(queue: int, said: str) -> None:
    """One thread busy, ``queue`` requests waiting for it: the next is refused at once,
    saying how many wait (it said "1 requests already wait" for one)."""
    gate = ComputeGate(threads=1, queue=queue, wait_s=30.0)
    refusals: list[str] = []

    async def scenario() -> None:
        release = anyio.Event()
        async with anyio.create_task_group() as tasks:
            tasks.start_soon(gate.run_async, release.wait)
            while gate.limiter.available_tokens or gate.waiting:  # the thread is taken
                await anyio.sleep(0.01)
            for _ in range(queue):
                tasks.start_soon(gate.run_async, release.wait)
            while gate.waiting < queue:
                await anyio.sleep(0.01)
            with pytest.raises(Overloaded) as refused:
                await gate.run_async(release.wait)
            refusals.append(str(refused.value.detail))
            release.set()

    anyio.run(scenario)
    assert refusals == [f"the service is past its capacity ({said} for CPU); try again in 1 s"]
