"""Answers about a record's arrays kept for the arrays that come back unchanged: an extraction
asks for a record's taps and noise floors in every stage, standard error and check.

An array counts as unchanged when it is the same object with the same sum and the same samples
at both ends and the middle (an in-place change is seen by the sum; the reference kept here
keeps the object, so its identity cannot be reused by another array)."""

from __future__ import annotations

from typing import Any, Callable

import numpy as np


def fingerprint(x) -> tuple | None:
    """What :class:`ArrayMemo` compares besides identity; None for anything but a non-empty
    1-D float array (never remembered)."""
    if not (isinstance(x, np.ndarray) and x.dtype == float and x.ndim == 1 and len(x)):
        return None
    return float(x.sum()), float(x[0]), float(x[len(x) // 2]), float(x[-1]), len(x)


class ArrayMemo:
    """``memo(fn, x, *args)`` = ``fn(x, *args)``, reused for the last ``size`` unchanged arrays."""

    def __init__(self, size: int = 1):
        self.size = size
        self._items: list = []  # (array, fingerprint and args, answer), newest first

    def __call__(self, fn: Callable[..., Any], x, *args):
        key = fingerprint(x)
        if key is None:
            return fn(x, *args)
        key = key + args
        for arr, k, value in self._items:
            if arr is x and k == key:
                return value
        value = fn(x, *args)
        self._items.insert(0, (x, key, value))
        del self._items[self.size :]
        return value
