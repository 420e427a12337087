"""MiniRocket features of multichannel rate series, written out in numpy and numba.

MiniRocket (Dempster, Schmidt and Webb, "MINIROCKET: A very fast (almost) deterministic
transform for time series classification", KDD 2021) turns a series into thousands of
"proportion of positive values" (PPV) features, on which a ridge classifier is fitted.
This module is our own implementation of the multivariate variant, following the paper
and the authors' reference code (``minirocket_multivariate.py``, the code sktime's and
aeon's ``MiniRocketMultivariate`` carry); neither package could be installed beside the
project's numpy / numba / pandas versions. What it does, as the paper does:

- **84 kernels** of length 9: every choice of 3 of the 9 taps gets weight +2, the other
  6 weight -1 (so each kernel sums to zero and the features are offset-invariant);
- **dilations** ``floor(2**e)`` for ``e`` evenly spaced from 0 to ``log2((T - 1) / 8)``,
  at most ``max_dilations_per_kernel`` of them, the feature budget shared out over them
  as the reference code does;
- **channels**: each (dilation, kernel) combination convolves the sum of a random subset
  of ``floor(2**u)`` channels, ``u ~ U(0, log2(min(C, 9) + 1))``; by linearity that equals
  summing the channels' own convolutions, as the reference code does;
- **biases** from quantiles of the convolution output of one randomly chosen training
  series, the quantiles taken from the golden-ratio low-discrepancy sequence
  ``(n * phi) mod 1``;
- **padding** alternates: combinations with ``(dilation index + kernel index)`` even use
  the zero-padded output (length T), the others only the valid part, without padding;
- **PPV**: the fraction of outputs greater than the bias.

The convolution is computed directly, tap by tap, rather than by the reference code's
pre-summed alpha / gamma arrays; the values are the same up to rounding. Randomness comes
from an explicit :class:`numpy.random.Generator`: the same generator state gives the same
parameters. Everything fitted is plain arrays (:class:`MiniRocketParameters`), so a model
is stored as JSON data.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

__all__ = [
    "KERNEL_LENGTH",
    "KERNEL_TRIPLETS",
    "KernelFeature",
    "MiniRocketParameters",
    "fit_minirocket",
    "minirocket_transform",
]

KERNEL_LENGTH = 9
# The taps weighted +2 of each of the 84 kernels, in the reference code's order.
KERNEL_TRIPLETS = np.array(list(itertools.combinations(range(KERNEL_LENGTH), 3)), dtype=np.int64)
_N_KERNELS = len(KERNEL_TRIPLETS)
_GOLDEN_RATIO = (math.sqrt(5.0) + 1.0) / 2.0


@dataclass(frozen=True)
class KernelFeature:
    """Where one feature comes from, spelled out (for checking and for reports).

    :param weights: the 9 kernel weights, -1 or +2.
    :param dilation: spacing of the taps, in samples.
    :param channels: channels summed before the convolution.
    :param bias: the PPV threshold, in the units of the convolution output.
    :param padded: True when the zero-padded output (length T) is used, False when only
        the samples the kernel covers without padding are.
    """

    weights: np.ndarray
    dilation: int
    channels: np.ndarray
    bias: float
    padded: bool


@dataclass(frozen=True)
class MiniRocketParameters:
    """A fitted MiniRocket transform: plain integer and float arrays.

    :param length: samples per series the transform was fitted for.
    :param n_channels: channels per series (3 for body rates).
    :param dilations: (D,) dilations in samples, increasing.
    :param features_per_dilation: (D,) features each kernel gets at each dilation.
    :param channels_per_combination: (84 D,) channels summed by each (dilation, kernel)
        combination, dilation-major.
    :param channel_indices: the channels of every combination, concatenated.
    :param biases: (84 * sum(features_per_dilation),) PPV thresholds.
    """

    length: int
    n_channels: int
    dilations: np.ndarray
    features_per_dilation: np.ndarray
    channels_per_combination: np.ndarray
    channel_indices: np.ndarray
    biases: np.ndarray

    @property
    def n_features(self) -> int:
        return len(self.biases)

    def check(self) -> MiniRocketParameters:
        """Return self if the arrays fit together, else raise ValueError saying how not."""
        d = len(self.dilations)
        if self.length < KERNEL_LENGTH or self.n_channels < 1:
            raise ValueError(
                f"MiniRocket needs length >= {KERNEL_LENGTH} and >= 1 channel, got length "
                f"{self.length}, {self.n_channels} channels"
            )
        if d < 1 or self.features_per_dilation.shape != (d,):
            raise ValueError(
                f"{d} dilations but features_per_dilation of shape "
                f"{self.features_per_dilation.shape}"
            )
        if np.any(self.dilations < 1) or np.any(
            (KERNEL_LENGTH - 1) * self.dilations > self.length - 1
        ):
            raise ValueError(
                f"dilations must lie in 1..{(self.length - 1) // (KERNEL_LENGTH - 1)} for "
                f"length {self.length}, got {self.dilations.tolist()}"
            )
        if np.any(self.features_per_dilation < 1):
            raise ValueError(
                f"features_per_dilation must be >= 1, got {self.features_per_dilation.tolist()}"
            )
        if self.channels_per_combination.shape != (_N_KERNELS * d,) or np.any(
            (self.channels_per_combination < 1) | (self.channels_per_combination > self.n_channels)
        ):
            raise ValueError(
                f"channels_per_combination must hold {_N_KERNELS * d} counts in "
                f"1..{self.n_channels}, got shape {self.channels_per_combination.shape}"
            )
        total = int(self.channels_per_combination.sum())
        if self.channel_indices.shape != (total,) or np.any(
            (self.channel_indices < 0) | (self.channel_indices >= self.n_channels)
        ):
            raise ValueError(
                f"channel_indices must hold {total} channels in 0..{self.n_channels - 1}, "
                f"got shape {self.channel_indices.shape}"
            )
        expected = _N_KERNELS * int(self.features_per_dilation.sum())
        if self.biases.shape != (expected,) or not np.all(np.isfinite(self.biases)):
            raise ValueError(
                f"biases must hold {expected} finite values, got shape {self.biases.shape}"
            )
        return self

    def to_dict(self) -> dict[str, Any]:
        return {
            "length": self.length,
            "n_channels": self.n_channels,
            "dilations": self.dilations.tolist(),
            "features_per_dilation": self.features_per_dilation.tolist(),
            "channels_per_combination": self.channels_per_combination.tolist(),
            "channel_indices": self.channel_indices.tolist(),
            "biases": self.biases.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MiniRocketParameters:
        return cls(
            length=int(data["length"]),
            n_channels=int(data["n_channels"]),
            dilations=np.asarray(data["dilations"], dtype=np.int64).reshape(-1),
            features_per_dilation=np.asarray(data["features_per_dilation"], dtype=np.int64).reshape(
                -1
            ),
            channels_per_combination=np.asarray(
                data["channels_per_combination"], dtype=np.int64
            ).reshape(-1),
            channel_indices=np.asarray(data["channel_indices"], dtype=np.int64).reshape(-1),
            biases=np.asarray(data["biases"], dtype=float).reshape(-1),
        ).check()

    def describe(self, feature: int) -> KernelFeature:
        """The kernel, dilation, channels, bias and padding behind feature ``feature``."""
        if not 0 <= feature < self.n_features:
            raise ValueError(f"feature must lie in 0..{self.n_features - 1}, got {feature!r}")
        starts = np.concatenate([[0], np.cumsum(self.features_per_dilation)])
        # Features are laid out dilation-major, then kernel, then bias.
        dilation_index = int(np.searchsorted(starts * _N_KERNELS, feature, side="right") - 1)
        within = feature - int(starts[dilation_index]) * _N_KERNELS
        kernel_index = within // int(self.features_per_dilation[dilation_index])
        combination = dilation_index * _N_KERNELS + kernel_index
        first = int(self.channels_per_combination[:combination].sum())
        count = int(self.channels_per_combination[combination])
        weights = -np.ones(KERNEL_LENGTH)
        weights[KERNEL_TRIPLETS[kernel_index]] = 2.0
        return KernelFeature(
            weights=weights,
            dilation=int(self.dilations[dilation_index]),
            channels=self.channel_indices[first : first + count].copy(),
            bias=float(self.biases[feature]),
            padded=(dilation_index + kernel_index) % 2 == 0,
        )


def _fit_dilations(
    length: int, n_features: int, max_dilations: int
) -> tuple[np.ndarray, np.ndarray]:
    # The reference code's rule: up to max_dilations exponentially spaced dilations, so
    # that the kernel (9 taps) spans at most the whole series; the features per kernel
    # are shared out over the distinct dilations, the remainder round-robin.
    per_kernel = n_features // _N_KERNELS
    n_dilations = min(per_kernel, max_dilations)
    multiplier = per_kernel / n_dilations
    max_exponent = math.log2((length - 1) / (KERNEL_LENGTH - 1))
    dilations, counts = np.unique(
        np.logspace(0, max_exponent, n_dilations, base=2).astype(np.int64), return_counts=True
    )
    per_dilation = (counts * multiplier).astype(np.int64)
    remainder = per_kernel - int(per_dilation.sum())
    i = 0
    while remainder > 0:
        per_dilation[i] += 1
        remainder -= 1
        i = (i + 1) % len(per_dilation)
    return dilations, per_dilation


def _quantiles(n: int) -> np.ndarray:
    return (np.arange(1, n + 1) * _GOLDEN_RATIO) % 1.0


@njit(cache=True)
def _convolve(
    x: np.ndarray, channels: np.ndarray, dilation: int, triplet: np.ndarray, out: np.ndarray
) -> None:
    """out[t] = sum_k w_k s[t + (k - 4) dilation], s the sum of the channels, zero-padded."""
    length = x.shape[1]
    summed = np.zeros(length)
    for c in channels:
        for t in range(length):
            summed[t] += x[c, t]
    out[:] = 0.0
    for k in range(9):
        weight = -1.0
        if k == triplet[0] or k == triplet[1] or k == triplet[2]:
            weight = 2.0
        shift = (k - 4) * dilation
        lo = max(0, -shift)
        hi = min(length, length - shift)
        for t in range(lo, hi):
            out[t] += weight * summed[t + shift]


@njit(cache=True)
def _bias_source_outputs(
    x: np.ndarray,
    examples: np.ndarray,
    dilations: np.ndarray,
    channels_per_combination: np.ndarray,
    channel_indices: np.ndarray,
    triplets: np.ndarray,
) -> np.ndarray:
    """Zero-padded convolution output of each combination on its chosen series."""
    n_kernels = triplets.shape[0]
    outputs = np.empty((dilations.shape[0] * n_kernels, x.shape[2]))
    combination = 0
    first_channel = 0
    for d in range(dilations.shape[0]):
        for kernel in range(n_kernels):
            count = channels_per_combination[combination]
            channels = channel_indices[first_channel : first_channel + count]
            _convolve(
                x[examples[combination]],
                channels,
                dilations[d],
                triplets[kernel],
                outputs[combination],
            )
            combination += 1
            first_channel += count
    return outputs


@njit(cache=True)
def _transform(
    x: np.ndarray,
    dilations: np.ndarray,
    features_per_dilation: np.ndarray,
    channels_per_combination: np.ndarray,
    channel_indices: np.ndarray,
    triplets: np.ndarray,
    biases: np.ndarray,
) -> np.ndarray:
    n, _, length = x.shape
    n_kernels = triplets.shape[0]
    features = np.empty((n, biases.shape[0]))
    out = np.empty(length)
    for s in range(n):
        feature = 0
        combination = 0
        first_channel = 0
        for d in range(dilations.shape[0]):
            dilation = dilations[d]
            padding = ((9 - 1) * dilation) // 2
            n_here = features_per_dilation[d]
            for kernel in range(n_kernels):
                count = channels_per_combination[combination]
                channels = channel_indices[first_channel : first_channel + count]
                _convolve(x[s], channels, dilation, triplets[kernel], out)
                lo = 0
                hi = length
                if (d + kernel) % 2 == 1:
                    lo = padding
                    hi = length - padding
                for f in range(n_here):
                    bias = biases[feature + f]
                    positive = 0
                    for t in range(lo, hi):
                        if out[t] > bias:
                            positive += 1
                    features[s, feature + f] = positive / (hi - lo)
                feature += n_here
                combination += 1
                first_channel += count
    return features


def _as_channels_first(X: Any) -> np.ndarray:
    arr = np.asarray(X, dtype=float)
    if arr.ndim != 3:
        raise ValueError(f"series must be shaped (n_series, length, channels), got {arr.shape}")
    return np.ascontiguousarray(arr.transpose(0, 2, 1))


def fit_minirocket(
    X: Any,
    rng: np.random.Generator,
    *,
    n_features: int = 10_000,
    max_dilations_per_kernel: int = 32,
) -> MiniRocketParameters:
    """Fit MiniRocket's dilations, channel subsets and biases to training series.

    :param X: (n_series, length, channels) training series; only their convolution
        outputs' quantiles are used (for the biases), so any units do.
    :param rng: draws the channel subsets and the series each bias comes from.
    :param n_features: feature budget; rounded down to a multiple of 84 (the paper's
        10 000 gives 9 996 features).
    :param max_dilations_per_kernel: at most this many dilations (the paper's 32).
    """
    if isinstance(n_features, bool) or not isinstance(n_features, int) or n_features < _N_KERNELS:
        raise ValueError(f"n_features must be an integer >= {_N_KERNELS}, got {n_features!r}")
    if (
        isinstance(max_dilations_per_kernel, bool)
        or not isinstance(max_dilations_per_kernel, int)
        or max_dilations_per_kernel < 1
    ):
        raise ValueError(
            f"max_dilations_per_kernel must be a positive integer, got {max_dilations_per_kernel!r}"
        )
    x = _as_channels_first(X)
    n_series, n_channels, length = x.shape
    if n_series < 1 or length < KERNEL_LENGTH:
        raise ValueError(
            f"MiniRocket needs at least one series of >= {KERNEL_LENGTH} samples, got "
            f"{n_series} of {length}"
        )
    dilations, per_dilation = _fit_dilations(length, n_features, max_dilations_per_kernel)
    n_combinations = _N_KERNELS * len(dilations)
    max_exponent = math.log2(min(n_channels, KERNEL_LENGTH) + 1)
    channels_per_combination = (2.0 ** rng.uniform(0.0, max_exponent, n_combinations)).astype(
        np.int64
    )
    channel_indices = np.concatenate(
        [rng.choice(n_channels, int(count), replace=False) for count in channels_per_combination]
    ).astype(np.int64)
    examples = rng.integers(n_series, size=n_combinations)
    quantiles = _quantiles(_N_KERNELS * int(per_dilation.sum()))
    outputs = _bias_source_outputs(
        x, examples, dilations, channels_per_combination, channel_indices, KERNEL_TRIPLETS
    )
    # Each combination's features take the next quantiles of the sequence, in order.
    ends = np.cumsum(np.repeat(per_dilation, _N_KERNELS))
    biases = np.concatenate(
        [
            np.quantile(output, quantiles[end - count : end])
            for output, end, count in zip(
                outputs, ends, np.repeat(per_dilation, _N_KERNELS), strict=True
            )
        ]
    )
    return MiniRocketParameters(
        length=length,
        n_channels=n_channels,
        dilations=dilations,
        features_per_dilation=per_dilation,
        channels_per_combination=channels_per_combination,
        channel_indices=channel_indices,
        biases=np.asarray(biases),
    ).check()


def minirocket_transform(X: Any, parameters: MiniRocketParameters) -> np.ndarray:
    """PPV features of each series, (n_series, n_features), each in [0, 1].

    :param X: (n_series, length, channels) series of the length and channel count the
        parameters were fitted for.
    :param parameters: from :func:`fit_minirocket`.
    """
    x = _as_channels_first(X)
    if x.shape[1:] != (parameters.n_channels, parameters.length):
        raise ValueError(
            f"series must be (n_series, {parameters.length}, {parameters.n_channels}), got "
            f"{np.asarray(X).shape}"
        )
    return np.asarray(
        _transform(
            x,
            parameters.dilations,
            parameters.features_per_dilation,
            parameters.channels_per_combination,
            parameters.channel_indices,
            KERNEL_TRIPLETS,
            parameters.biases,
        )
    )
