"""Shared test set-up.  Randomness in tests is always seeded."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
