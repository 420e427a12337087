"""PPO search (stable-baselines3) over the sequence-search environment.

torch and stable-baselines3 take seconds to import: they are imported by
:func:`ppo_search` when it runs, never with the package (the progress callback, which
subclasses stable-baselines3's, is :mod:`inertia_id.search.callback`).
"""

from __future__ import annotations

import math
import os
from typing import Any, Unpack

from ..errors import InputError
from ..physics.scenario import Scenario
from .loop import RunOptions, SearchRun, check_budget, overrides
from .records import SearchResult

__all__ = ["PPO_DEFAULTS", "check_ppo_params", "ppo_search"]

#: The paper's PPO hyperparameters (stable-baselines3 names).
PPO_DEFAULTS: dict[str, Any] = {
    "n_steps": 2048,
    "learning_rate": 3e-4,
    "batch_size": 64,
    "n_epochs": 10,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_range": 0.2,
    "ent_coef": 0.05,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
}

_POSITIVE_INT = ("n_steps", "batch_size", "n_epochs")
# Beyond this a rollout buffer or an update loop would exhaust memory or time.
_LARGEST = 1e7
_UNIT_INTERVAL = ("gamma", "gae_lambda")
_POSITIVE = ("learning_rate", "clip_range", "max_grad_norm")
_NON_NEGATIVE = ("ent_coef", "vf_coef")


def _is_whole(value: int | float) -> bool:
    return isinstance(value, int) or (math.isfinite(value) and float(value).is_integer())


def check_ppo_params(params: dict[str, Any] | None) -> dict[str, Any]:
    """The paper's defaults updated with ``params``, each checked; unknown names refused."""
    merged = overrides(params, PPO_DEFAULTS, "unknown PPO parameters {unknown}; allowed: {known}")
    for name, value in merged.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputError(f"PPO parameter {name} must be a number, got {value!r}")
        if abs(value) > _LARGEST:
            raise InputError(f"PPO parameter {name} must be at most {_LARGEST:g}, got {value!r}")
        if name in _POSITIVE_INT and (not _is_whole(value) or value < 1):
            raise InputError(f"PPO parameter {name} must be a positive integer, got {value!r}")
        if name in _UNIT_INTERVAL and not 0 <= value <= 1:
            raise InputError(f"PPO parameter {name} must lie in [0, 1], got {value!r}")
        if name in _POSITIVE and not value > 0:
            raise InputError(f"PPO parameter {name} must be > 0, got {value!r}")
        if name in _NON_NEGATIVE and not value >= 0:
            raise InputError(f"PPO parameter {name} must be >= 0, got {value!r}")
    for name in _POSITIVE_INT:
        merged[name] = int(merged[name])
    if merged["batch_size"] < 2:
        # stable-baselines3 normalises advantages over a minibatch: one sample is refused.
        raise InputError(f"PPO parameter batch_size must be at least 2, got {merged['batch_size']}")
    if merged["batch_size"] > merged["n_steps"]:
        raise InputError(
            f"PPO batch_size ({merged['batch_size']}) must not exceed n_steps ({merged['n_steps']})"
        )
    return merged


def ppo_search(
    scenario: Scenario,
    *,
    sequence_length: int = 4,
    total_timesteps: int = 20_480,
    lagrangian_lr: float = 0.0,
    ppo_params: dict[str, Any] | None = None,
    patience_episodes: int | None = 500,
    policy_path: str | os.PathLike[str] | None = None,
    **options: Unpack[RunOptions],
) -> SearchResult:
    """Train PPO on the sequence-search environment and return the best sequence it met.

    :param total_timesteps: environment steps of training.
    :param ppo_params: overrides of :data:`PPO_DEFAULTS` (the paper's values).
    :param patience_episodes: stop once the best F1 is 1 and nothing better came for
        this many episodes; None trains for the whole budget.
    :param policy_path: where to save the trained policy (stable-baselines3 zip; a name
        with no suffix gets ".zip", as stable-baselines3 adds it), whole or not at all
        (:func:`~inertia_id.files.write_whole`).
    :param options: fuel weight, seed (of the noise, the policy and PPO's sampling),
        scorer settings, constraints, constraint penalty (the starting Lagrange
        multiplier), fresh draws, the progress and cancel hooks and the time limit
        (both polled every step): see :class:`~inertia_id.search.loop.SearchRun`.
    :param lagrangian_lr: with a value > 0, the multiplier is updated after every
        rollout by dual ascent, ``λ ← max(0, λ + lr · mean violation)`` (PPO-Lagrangian):
        it grows while the policy's sequences break the constraints and stays once they
        hold; 0 keeps a fixed penalty.
    """
    if not (isinstance(lagrangian_lr, int | float) and 0 <= lagrangian_lr < 1e6):
        raise InputError(f"lagrangian_lr must be a number in [0, 1e6), got {lagrangian_lr!r}")
    check_budget("total_timesteps", total_timesteps, sequence_length)
    params = check_ppo_params(ppo_params)
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger

    from .callback import SearchCallback

    run = SearchRun(scenario, sequence_length, patience_episodes, **options)
    callback = SearchCallback(
        run.tracker,
        total_timesteps,
        run.progress,
        run.should_stop,
        env=run.env if lagrangian_lr > 0 and run.env.constraints else None,
        lagrangian_lr=float(lagrangian_lr),
        deadline=run.deadline,
    )
    threads = torch.get_num_threads()
    # A small MLP: one thread is as fast, and keeps the learning curve reproducible.
    torch.set_num_threads(1)
    try:
        model = PPO("MlpPolicy", run.env, seed=run.seed, device="cpu", verbose=0, **params)
        # A logger of ours that writes nowhere: without one, learn() configures its own,
        # which makes an empty SB3-<date> folder in the temporary directory even at
        # verbose 0, one for every PPO search a serve runs. The learning curve is ours
        # (SearchCallback), so SB3's log is not wanted.
        model.set_logger(Logger(folder=None, output_formats=[]))
        model.learn(total_timesteps=total_timesteps, callback=callback)
        saved = None
        if policy_path is not None:
            saved = _save_whole(model, policy_path)
    finally:
        torch.set_num_threads(threads)
    run.close_curve(total_timesteps)
    return run.finish(
        "ppo",
        stopped=callback.stopped,
        settings={
            "timesteps": total_timesteps,
            "patience_episodes": patience_episodes,
            "ppo": params,
            "lagrangian_lr": lagrangian_lr,
            "final_constraint_penalty": run.env.constraint_penalty,
        },
        policy_path=saved,
    )


def _save_whole(model: Any, policy_path: str | os.PathLike[str]) -> str:
    """Save ``model`` to ``policy_path`` whole or not at all, and say where it went.

    stable-baselines3 writes its zip in place: a save that failed part-way (a full disk)
    left a truncated zip under the name asked for. Given an open file, it writes the zip
    there and leaves the file open, so :func:`~inertia_id.files.write_whole` hands it the
    file beside the target that it renames over it. The name follows stable-baselines3's
    own rule (".zip" added to a name with no suffix; it wrote ``p.bin`` where ``p.bin.zip``
    was reported) and its missing folders are made, as stable-baselines3 made them.
    """
    from pathlib import Path

    from ..files import write_whole

    path = Path(policy_path)
    if path.suffix == "":
        path = path.with_name(f"{path.name}.zip")
    path.parent.mkdir(parents=True, exist_ok=True)
    write_whole(path, model.save)
    return os.fspath(path)
