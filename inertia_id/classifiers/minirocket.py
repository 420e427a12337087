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

:class:`MiniRocketClassifier` (kind ``"minirocket"``) puts a ridge classifier on the
features.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numba import njit
from scipy.spatial.distance import cdist

from ..checks import is_integer
from ..errors import InputError
from .base import SupervisedClassifier, check_int

__all__ = [
    "KERNEL_LENGTH",
    "KERNEL_TRIPLETS",
    "KernelFeature",
    "MiniRocketClassifier",
    "MiniRocketParameters",
    "fit_minirocket",
    "minirocket_transform",
    "warm_up",
]

KERNEL_LENGTH = 9
# The taps weighted +2 of each of the 84 kernels, in the reference code's order.
KERNEL_TRIPLETS = np.array(list(itertools.combinations(range(KERNEL_LENGTH), 3)), dtype=np.int64)
_N_KERNELS = len(KERNEL_TRIPLETS)
_GOLDEN_RATIO = (math.sqrt(5.0) + 1.0) / 2.0
# The paper's (and the reference code's) ridge penalties.
DEFAULT_ALPHAS = tuple(float(a) for a in np.logspace(-3, 3, 10))


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
        """Return self if the arrays fit together, else raise InputError saying how not."""
        d = len(self.dilations)
        if self.length < KERNEL_LENGTH or self.n_channels < 1:
            raise InputError(
                f"MiniRocket needs length >= {KERNEL_LENGTH} and >= 1 channel, got length "
                f"{self.length}, {self.n_channels} channels"
            )
        if d < 1 or self.features_per_dilation.shape != (d,):
            raise InputError(
                f"{d} dilations but features_per_dilation of shape "
                f"{self.features_per_dilation.shape}"
            )
        if np.any(self.dilations < 1) or np.any(
            (KERNEL_LENGTH - 1) * self.dilations > self.length - 1
        ):
            raise InputError(
                f"dilations must lie in 1..{(self.length - 1) // (KERNEL_LENGTH - 1)} for "
                f"length {self.length}, got {self.dilations.tolist()}"
            )
        if np.any(self.features_per_dilation < 1):
            raise InputError(
                f"features_per_dilation must be >= 1, got {self.features_per_dilation.tolist()}"
            )
        if self.channels_per_combination.shape != (_N_KERNELS * d,) or np.any(
            (self.channels_per_combination < 1) | (self.channels_per_combination > self.n_channels)
        ):
            raise InputError(
                f"channels_per_combination must hold {_N_KERNELS * d} counts in "
                f"1..{self.n_channels}, got shape {self.channels_per_combination.shape}"
            )
        total = int(self.channels_per_combination.sum())
        if self.channel_indices.shape != (total,) or np.any(
            (self.channel_indices < 0) | (self.channel_indices >= self.n_channels)
        ):
            raise InputError(
                f"channel_indices must hold {total} channels in 0..{self.n_channels - 1}, "
                f"got shape {self.channel_indices.shape}"
            )
        expected = _N_KERNELS * int(self.features_per_dilation.sum())
        if self.biases.shape != (expected,) or not np.all(np.isfinite(self.biases)):
            raise InputError(
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
            raise InputError(f"feature must lie in 0..{self.n_features - 1}, got {feature!r}")
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
        raise InputError(f"series must be shaped (n_series, length, channels), got {arr.shape}")
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
    if not is_integer(n_features, minimum=_N_KERNELS, numpy=False):
        raise InputError(f"n_features must be an integer >= {_N_KERNELS}, got {n_features!r}")
    if not is_integer(max_dilations_per_kernel, minimum=1, numpy=False):
        raise InputError(
            f"max_dilations_per_kernel must be a positive integer, got {max_dilations_per_kernel!r}"
        )
    x = _as_channels_first(X)
    n_series, n_channels, length = x.shape
    if n_series < 1 or length < KERNEL_LENGTH:
        raise InputError(
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
        raise InputError(
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


class MiniRocketClassifier(SupervisedClassifier):
    """MiniRocket features and a ridge classifier (Dempster et al. 2021).

    The transform is the one above (our implementation, following the paper; aeon and
    sktime cannot be installed beside the project's pinned stack). The features are
    scaled to unit variance over the training set, as the reference
    pipeline does, and scikit-learn's ``RidgeClassifierCV`` picks the penalty by
    leave-one-out. The scaling is folded into the stored coefficients.

    ``transform`` gives, for each candidate k, the Euclidean distance from the ridge's
    decision vector d (one value per candidate; the ridge targets are +1 for the true
    candidate and -1 for the others) to candidate k's target code: 0 for a series the
    ridge maps exactly onto k's code, 2 sqrt(2) between two codes. The nearest code is
    the largest decision value, so ``predict`` is the ridge classifier's prediction. A
    distance rather than the negative decision value, because a response unlike any
    candidate (a far-off inertia, no response at all) is extrapolated by the linear model
    to a decision vector far from every code, while its largest decision value can look
    ordinary; the distance lets "matches none" work. The novelty thresholds use the
    leave-one-out decision vectors of the training series (closed form, at the chosen
    penalty).

    :param n_features: MiniRocket feature budget (the paper's 10 000; rounded down to a
        multiple of 84).
    :param max_dilations_per_kernel: the paper's 32.
    :param alphas: ridge penalties to choose from; None = the paper's
        ``logspace(-3, 3, 10)``.
    :param novelty_factor: see
        :meth:`~inertia_id.classifiers.base.BaseClassifier.novelty_thresholds`.
    :param random_state: seed of the channel subsets and bias draws.
    """

    kind: ClassVar[str] = "minirocket"
    LISTING_ORDER = 40
    LABEL = "MiniRocket + ridge (supervised)"
    #: What the sweep and the report print as the metric.
    metric = "minirocket"

    def __init__(
        self,
        *,
        n_features: int = 10_000,
        max_dilations_per_kernel: int = 32,
        alphas: Sequence[float] | None = None,
        novelty_factor: float = 1.5,
        random_state: int | None = None,
    ) -> None:
        self.n_features = n_features
        self.max_dilations_per_kernel = max_dilations_per_kernel
        self.alphas = alphas
        self.novelty_factor = novelty_factor
        self.random_state = random_state

    def _check_params(self) -> None:
        super()._check_params()
        check_int("n_features", self.n_features, minimum=84)
        check_int("max_dilations_per_kernel", self.max_dilations_per_kernel)
        if self.alphas is not None:
            alphas = np.asarray(self.alphas, dtype=float)
            if (
                alphas.ndim != 1
                or alphas.size < 1
                or not np.all(np.isfinite(alphas) & (alphas > 0))
            ):
                raise InputError(f"alphas must be numbers > 0, got {self.alphas!r}")
        if self.random_state is not None:
            check_int("random_state", self.random_state, minimum=0)

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        rng = np.random.default_rng(self.random_state)
        self.parameters_ = fit_minirocket(
            X,
            rng,
            n_features=int(self.n_features),
            max_dilations_per_kernel=int(self.max_dilations_per_kernel),
        )
        features = minirocket_transform(X, self.parameters_)
        self._checkpoint()
        std = features.std(axis=0)
        scale = np.where(std > 10 * np.finfo(float).eps, std, 1.0)
        scaled = features / scale
        alphas = DEFAULT_ALPHAS if self.alphas is None else tuple(float(a) for a in self.alphas)
        # scikit-learn's linear models: imported where they are used, not with the package.
        from sklearn.linear_model import RidgeClassifierCV

        ridge = RidgeClassifierCV(alphas=alphas).fit(scaled, y)
        self.alpha_ = float(ridge.alpha_)
        # One row per candidate, or a single row (candidate 1's) for two candidates.
        # C order, as a loaded document has it: the same memory layout makes the matrix
        # product, and so a round trip's predictions, identical to the last bit.
        self.coef_ = np.ascontiguousarray(np.atleast_2d(np.asarray(ridge.coef_, float)) / scale)
        self.intercept_ = np.asarray(ridge.intercept_, dtype=float).reshape(-1)
        targets = -np.ones((len(y), self.n_candidates_))
        targets[np.arange(len(y)), y] = 1.0
        if self.n_candidates_ == 2:
            targets = targets[:, 1:]  # scikit-learn's single column for two classes
        left_out = _leave_one_out_ridge(scaled, targets, self.alpha_)
        return _distance_to_codes(_per_candidate(left_out))

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        decision = minirocket_transform(X, self.parameters_) @ self.coef_.T + self.intercept_
        return _distance_to_codes(_per_candidate(decision))

    @classmethod
    def stored_numbers(cls, n_candidates: int, values: int, n_realisations: int) -> int:
        """The ridge's weights, a row a candidate over the features, the features' biases,
        and the transform's dilations and channels (at most 84 x 32 combinations of at
        most 3 channels, under two more rows), at the default 10,000 features."""
        return (n_candidates + 3) * 10_000

    def _model_state(self) -> dict[str, Any]:
        return {
            "transform": self.parameters_.to_dict(),
            "coef": self.coef_.tolist(),
            "intercept": self.intercept_.tolist(),
            "alpha": self.alpha_,
        }

    def _load_model_state(self, state: dict[str, Any]) -> None:
        parameters = MiniRocketParameters.from_dict(state["transform"])
        coef = np.asarray(state["coef"], dtype=float)
        intercept = np.asarray(state["intercept"], dtype=float).reshape(-1)
        rows = 1 if self.n_candidates_ == 2 else self.n_candidates_
        if (
            parameters.length != self.length_
            or coef.shape != (rows, parameters.n_features)
            or intercept.shape != (rows,)
        ):
            raise InputError(
                f"ridge coefficients of shape {coef.shape} and {intercept.shape} intercepts "
                f"for {self.n_candidates_} candidates and {parameters.n_features} features"
            )
        self.parameters_ = parameters
        self.coef_ = coef
        self.intercept_ = intercept
        self.alpha_ = float(state["alpha"])


def _per_candidate(decision: np.ndarray) -> np.ndarray:
    """Ridge decision values as (n, K); two classes come as one column (class 1's)."""
    return np.hstack([-decision, decision]) if decision.shape[1] == 1 else decision


def _distance_to_codes(decision: np.ndarray) -> np.ndarray:
    """Euclidean distance of each (K,) decision vector to each candidate's target code.

    The code of candidate k is +1 at k and -1 elsewhere, so the squared distance is
    ``|d|^2 + K - 4 d_k + 2 sum(d)``: the nearest code is the largest decision value,
    the ridge classifier's own prediction.
    """
    k = decision.shape[1]
    codes = 2.0 * np.eye(k) - 1.0
    return np.asarray(cdist(decision, codes))


def _leave_one_out_ridge(features: np.ndarray, targets: np.ndarray, alpha: float) -> np.ndarray:
    """Leave-one-out predictions of ridge regression with an unpenalised intercept.

    The residuals of the full fit are ``R Y`` with ``R = I - H`` (H the hat matrix), and
    the prediction for series i from a fit without it is ``y_i - (R Y)_i / R_ii`` (the
    identity scikit-learn's RidgeCV chooses alpha with). With B an orthonormal basis of
    the vectors orthogonal to the constant (the intercept absorbs the constant) and
    ``B^T F = U S W^T``, ``R = G diag(alpha / (s^2 + alpha)) G^T`` with ``G = B U``: a sum
    of positive terms, so R_ii stays accurate when it is tiny (small alpha, more features
    than series), where ``1 - H_ii`` would cancel. n x n work only.
    """
    n = len(features)
    basis = np.linalg.qr(np.ones((n, 1)), mode="complete")[0][:, 1:]
    u, s, _ = np.linalg.svd(basis.T @ features, full_matrices=False)
    g = basis @ u
    weights = alpha / (s**2 + alpha)
    residuals = g @ (weights[:, None] * (g.T @ targets))
    leverage_complement = (g**2) @ weights
    return np.asarray(targets - residuals / leverage_complement[:, None])


def warm_up() -> None:
    """Compile, or load from numba's cache, the transform's kernels on a tiny input."""
    X = np.random.default_rng(0).standard_normal((2, 16, 3))
    minirocket_transform(X, fit_minirocket(X, np.random.default_rng(0), n_features=84))
