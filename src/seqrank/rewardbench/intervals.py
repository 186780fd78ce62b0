"""95% intervals over seeds for measures that have a range (an accuracy in [0, 1], a rank
correlation in [-1, 1], a difference of two of them), from few seeds.

A t-interval on the values themselves runs past the range with 2 or 3 seeds (t has 1 or 2
degrees of freedom: 12.7 or 4.3 standard errors), and clipping it hides how little is
known. The interval here is a t-interval on the logit of each value's place in its range,
mapped back: it never leaves the range, it is as wide as the seeds say, and near the
middle of the range it is the plain t-interval. For a correlation in [-1, 1] the logit of
(1 + r) / 2 is twice Fisher's z, so this is Fisher's interval with a t quantile. A value
on the boundary (an accuracy of 1) is taken as `EDGE` of the range inside it, so that its
logit is finite. One seed gives no interval: low and high are None.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import special, stats

Interval = tuple[float, float | None, float | None]  # mean, low, high (None: one seed)
EDGE = 1e-3  # of the range: how far inside it a value on its boundary is taken to lie


def bounded_interval(values: Sequence[float], low: float, high: float) -> Interval:
    """The mean of `values` (each in [low, high]) and its 95% interval over them."""
    array = np.asarray(values, np.float64)
    mean = float(array.mean())
    if len(array) < 2:
        return mean, None, None
    if np.all(array == array[0]):
        return mean, mean, mean
    place = np.clip((array - low) / (high - low), EDGE, 1 - EDGE)
    logits = special.logit(place)
    half = stats.t.ppf(0.975, len(array) - 1) * logits.std(ddof=1) / np.sqrt(len(array))
    ends = special.expit(logits.mean() + np.array([-half, half])) * (high - low) + low
    return mean, float(ends[0]), float(ends[1])
