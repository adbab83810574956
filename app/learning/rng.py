"""Seeds: every random choice of the learner and the simulated study derives from one integer.

BoTorch and GPyTorch draw from torch's global generator (initial conditions, MC samples, prior
resampling on fit retries) and ``PairwiseGP._update`` perturbs its Newton start with numpy's global
generator, so reproducibility needs both seeded, scoped so the caller's streams are not disturbed.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np


def derive_seed(*parts: int) -> int:
    """A 63-bit seed derived from integers, e.g. ``(study seed, trial index)``."""
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(2, np.uint64)[0] >> 1)


@contextmanager
def seeded(seed: int) -> Iterator[None]:
    """Run the block with torch's and numpy's global generators seeded, then restore them."""
    import torch  # here, so that derive_seed stays usable without torch (worker's parent side)

    np_state = np.random.get_state()
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        np.random.seed(seed % 2**32)
        try:
            yield
        finally:
            np.random.set_state(np_state)
