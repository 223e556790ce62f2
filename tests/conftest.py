"""Shared test set-up.  Randomness in tests is always seeded.

Tests draw their seed at random (``np.random.SeedSequence().entropy``) and print it on
failure.  To replay a failure, set ``CURLTRACK_TEST_SEED`` to the printed seed: every
seed drawn that way then starts from it.
"""

import os

os.environ.setdefault("MPLBACKEND", "Agg")

if os.environ.get("CURLTRACK_TEST_SEED"):
    import numpy as np

    _REPLAY = int(os.environ["CURLTRACK_TEST_SEED"])
    _SeedSequence = np.random.SeedSequence

    class _ReplayedSeedSequence(_SeedSequence):
        def __init__(self, entropy=None, **kwargs):
            super().__init__(_REPLAY if entropy is None else entropy, **kwargs)

    np.random.SeedSequence = _ReplayedSeedSequence
