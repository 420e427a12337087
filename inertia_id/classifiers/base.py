"""What every classifier kind shares: its scores, and storage as a checksummed document.

A kind subclasses :class:`StoredClassifier` (before scikit-learn's ``BaseEstimator``),
names its document ``FORMAT``, and implements ``predict``, ``to_dict`` and ``from_dict``;
fitted, it has ``n_candidates_``.
"""

from __future__ import annotations

import os
from typing import Any, ClassVar, Self

import numpy as np

from . import documents

__all__ = ["StoredClassifier", "check_labels", "confusion_scores"]


def check_labels(y: Any, n_series: int, n_candidates: int | None = None) -> np.ndarray:
    """Candidate indices, one per series, each in 0..K-1 (K inferred when not given)."""
    arr = np.asarray(y)
    if arr.shape != (n_series,):
        raise ValueError(f"y must hold one label per series ({n_series}), got shape {arr.shape}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        if (
            not np.issubdtype(arr.dtype, np.number)
            or not np.all(np.isfinite(arr))
            or np.any(arr != np.round(arr))
        ):
            raise ValueError(f"labels must be candidate indices, got {arr.tolist()[:10]}")
    arr = arr.astype(int)
    upper = n_candidates if n_candidates is not None else (int(arr.max()) + 1 if arr.size else 0)
    outside = sorted({int(v) for v in arr if v < 0 or v >= upper})
    if outside:
        raise ValueError(f"labels must lie in 0..{upper - 1} (candidate indices), got {outside}")
    return arr


def confusion_scores(confusion: np.ndarray) -> dict[str, Any]:
    """Macro F1 (over the candidates present), accuracy and the confusion matrix itself."""
    tp = np.diag(confusion).astype(float)
    denom = confusion.sum(axis=0) + confusion.sum(axis=1)
    present = confusion.sum(axis=1) > 0
    f1 = np.divide(2.0 * tp, denom, out=np.zeros_like(tp), where=denom > 0)
    return {
        "f1": float(f1[present].mean()) if present.any() else 0.0,
        "accuracy": float(np.trace(confusion) / max(confusion.sum(), 1)),
        "confusion": confusion,
    }


class StoredClassifier:
    """Scores and storage, the same for every kind."""

    FORMAT: ClassVar[str] = ""
    n_candidates_: int

    def predict(self, X: Any) -> np.ndarray:
        raise NotImplementedError

    def to_dict(self) -> dict[str, Any]:
        raise NotImplementedError

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Self:
        raise NotImplementedError

    def evaluate(self, X: Any, y: Any) -> dict[str, Any]:
        """F1 (macro), accuracy and confusion matrix (row = true) of predictions against ``y``."""
        predicted = self.predict(X)
        labels = check_labels(y, len(predicted), self.n_candidates_)
        confusion = np.zeros((self.n_candidates_, self.n_candidates_), dtype=int)
        np.add.at(confusion, (labels, predicted), 1)
        return confusion_scores(confusion)

    def score(self, X: Any, y: Any) -> float:
        """Macro F1 of the predictions (the paper's score)."""
        return float(self.evaluate(X, y)["f1"])

    def to_json(self) -> str:
        """The fitted classifier as a checksummed JSON document."""
        return documents.write(self.FORMAT, self.to_dict())

    @classmethod
    def from_json(cls, text: str | bytes) -> Self:
        """Load a document written by :meth:`to_json`, verifying its checksum."""
        return cls.from_dict(documents.read(text, cls.FORMAT))

    def save(self, path: str | os.PathLike[str]) -> None:
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(self.to_json())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        with open(path, encoding="utf-8") as fh:
            return cls.from_json(fh.read())
