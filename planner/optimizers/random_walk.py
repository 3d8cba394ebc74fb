"""Many independent ±1 random walks, sampled a block of steps at a time.

ALO needs, for every ant, every dimension and every iteration, one point of a
T-step walk plus that walk's minimum and maximum (its min-max normalisation,
ALO eq. 2.7). Drawing T coin flips per walk is O(N·D·T) per iteration. Here each
group of 16 steps is one random 16-bit integer, and tables give a block's sum and
its lowest and highest partial sums, so a walk costs T/16 table look-ups. The
walks have exactly the distribution of step-by-step coin flips.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

_BLOCK = 16


def _block_tables() -> tuple[NDArray[np.int16], NDArray[np.int8], NDArray[np.int8]]:
    codes = np.arange(1 << _BLOCK, dtype=np.uint32)
    bits = (codes[:, None] >> np.arange(_BLOCK, dtype=np.uint32)) & 1
    partial = np.cumsum(2 * bits.astype(np.int8) - 1, axis=1, dtype=np.int8)
    popcount = bits.sum(axis=1, dtype=np.int16)
    return popcount, partial.min(axis=1), partial.max(axis=1)


_POPCOUNT, _BLOCK_MIN, _BLOCK_MAX = _block_tables()


def random_walks(
    rng: np.random.Generator, count: int, steps: int, at: int
) -> tuple[NDArray[np.int32], NDArray[np.int32], NDArray[np.int32]]:
    """For `count` walks of `steps` steps from 0: the position after `at` steps, the minimum
    and the maximum over all `steps + 1` positions (the start 0 included)."""
    if not 0 <= at <= steps:
        raise ValueError(f"at={at} is outside 0..{steps}")
    full, rest = divmod(steps, _BLOCK)
    blocks = rng.integers(0, 1 << _BLOCK, size=(count, full), dtype=np.uint16)
    sums = 2 * _POPCOUNT[blocks].astype(np.int32) - _BLOCK
    starts = np.cumsum(sums, axis=1, dtype=np.int32) - sums
    low = np.minimum(0, (starts + _BLOCK_MIN[blocks]).min(axis=1, initial=0))
    high = np.maximum(0, (starts + _BLOCK_MAX[blocks]).max(axis=1, initial=0))
    end = starts[:, -1] + sums[:, -1] if full else np.zeros(count, dtype=np.int32)

    tail = end[:, None] + np.cumsum(
        2 * rng.integers(0, 2, size=(count, rest), dtype=np.int32) - 1, axis=1
    )
    low = np.minimum(low, tail.min(axis=1, initial=0))
    high = np.maximum(high, tail.max(axis=1, initial=0))

    block, offset = divmod(at, _BLOCK)
    if block < full:
        mask = np.uint16((1 << offset) - 1)
        value = starts[:, block] + 2 * _POPCOUNT[blocks[:, block] & mask] - offset
    elif offset:
        value = tail[:, offset - 1]
    else:
        value = end
    return value.astype(np.int32), low.astype(np.int32), high.astype(np.int32)
