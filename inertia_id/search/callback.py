"""The PPO search's progress callback, in stable-baselines3's callback style.

Imported by :func:`~inertia_id.search.ppo.ppo_search` when it runs: subclassing
stable-baselines3's ``BaseCallback`` imports torch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import KW_ONLY, InitVar, dataclass, field
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

from .loop import CANCELLED, TIME_LIMIT, Deadline, report_point
from .records import SearchProgress, SearchTracker

__all__ = ["SearchCallback"]


# Compared and shown as an object, as stable-baselines3's callbacks are.
@dataclass(eq=False, repr=False)
class SearchCallback(BaseCallback):
    """Follows PPO's episodes: best sequence, learning curve, cancel and early stop.

    At the end of every rollout a curve point (mean episode reward, mean and best F1)
    is added and ``progress`` called with it: this is what feeds a reward curve while
    training runs. Training stops at the next environment step when ``should_stop()``
    says so (a cancel), when ``deadline`` has expired (the time limit) or when the
    tracker reached its target (F1 = 1 and no better sequence for ``patience_episodes``
    episodes).

    :param tracker: collects episodes and the curve.
    :param total_timesteps: the training budget, for progress fractions.
    :param progress: called with a :class:`SearchProgress` after every rollout.
    :param should_stop: polled every environment step; True cancels training.
    :param env: the environment whose ``constraint_penalty`` (the Lagrange multiplier)
        is updated after every rollout; None keeps it fixed.
    :param lagrangian_lr: the dual-ascent step: ``λ ← max(0, λ + lr · mean violation)``
        over the rollout's episodes.
    :param deadline: the search's time budget, checked every environment step; None:
        none.
    """

    tracker: SearchTracker
    total_timesteps: int
    progress: Callable[[SearchProgress], None] | None = None
    should_stop: Callable[[], bool] | None = None
    _: KW_ONLY
    env: InitVar[Any] = None
    lagrangian_lr: float = 0.0
    deadline: Deadline | None = None
    stopped: str = field(default="budget", init=False)

    def __post_init__(self, env: Any) -> None:
        super().__init__()
        # Not ``env``: stable-baselines3 names the env it trains in ``training_env``.
        self.constrained_env = env

    def _on_step(self) -> bool:
        rewards, dones, infos = self.locals["rewards"], self.locals["dones"], self.locals["infos"]
        for reward, done, info in zip(rewards, dones, infos, strict=True):
            self.tracker.on_step(float(reward), bool(done), info)
        if self.should_stop is not None and self.should_stop():
            self.stopped = CANCELLED
            return False
        # Not before one whole episode: a search stopped by its limit ends with a best.
        if self.deadline is not None and self.tracker.best is not None and self.deadline.expired():
            self.stopped = TIME_LIMIT
            return False
        if self.tracker.reached_target():
            self.stopped = "target"
            return False
        return True

    def _on_rollout_end(self) -> None:
        if self.constrained_env is not None:
            multiplier = self.constrained_env.constraint_penalty
            step = self.lagrangian_lr * self.tracker.mean_violation()
            self.constrained_env.constraint_penalty = max(0.0, multiplier + step)
        report_point(self.tracker, self.total_timesteps, self.progress)
