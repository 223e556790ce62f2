"""Robust statistics for the per-frame loops: :mod:`curltrack._stats` (one definition)."""

from .._stats import median, robust_sigma

__all__ = ["median", "robust_sigma"]
