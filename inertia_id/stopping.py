"""Stopping a training part-way: the caller's ``should_stop``, polled at checkpoints.

A training (:func:`~inertia_id.pipelines.train_for_sequence`) calls its checkpoint
between its pieces of work: after each simulation, between the folds of a covariance's
shrinkage, between the marginal kind's noise conditions, around a library's fit that
has no hook of its own. A checkpoint whose ``should_stop`` says True raises
:class:`TrainingStopped`, so nothing half-trained is returned; the caller knows why it
asked (a cancel, its worker stopping, a time limit) and says so.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["Checkpoint", "TrainingStopped", "checkpoint_of", "no_checkpoint"]

#: Called between two pieces of a training; raises :class:`TrainingStopped` to stop it.
Checkpoint = Callable[[], None]


class TrainingStopped(Exception):
    """A training stopped part-way because its caller's ``should_stop`` said so."""


def no_checkpoint() -> None:
    """The checkpoint of a training nobody stops: it goes on."""


def checkpoint_of(should_stop: Callable[[], bool] | None) -> Checkpoint:
    """The checkpoint that asks ``should_stop`` (None: :func:`no_checkpoint`).

    It asks at every call: a caller whose answer costs something (a database read)
    throttles it itself, as the worker's job context does.
    """
    if should_stop is None:
        return no_checkpoint

    def checkpoint() -> None:
        if should_stop():
            raise TrainingStopped("the training was asked to stop; stopped part-way")

    return checkpoint
