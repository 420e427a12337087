"""Rate series: the (n_series, length, 3) arrays in rad/s that classifiers and the
inertia estimator take."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["check_series"]


def check_series(X: Any) -> np.ndarray:
    """``X`` as a float (n_series, length, 3) array of finite rates, or an
    :class:`~inertia_id.errors.InputError` quoting the fault.

    :param X: one series (length, 3) or a batch (n_series, length, 3), rad/s.
    """
    try:
        arr = np.asarray(X, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"series must be numeric rates in rad/s: {exc}") from None
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InputError(f"series must be shaped (n_series, length, 3) in rad/s, got {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        i, t, axis = (int(v) for v in bad[0])
        raise InputError(
            f"series {i}, sample {t}, axis {axis} is {float(arr[i, t, axis])!r}; rates must be "
            f"finite ({len(bad)} non-finite values in all)"
        )
    return arr
