#!/usr/bin/env python
"""Campaign example: a session of shots on a sheet whose friction varies periodically.

Three draws (random speeds and spins of both directions, released from the same hack)
are integrated by the tests' independent integrator (``tests/discover/_world.py``) with a
hidden friction field 1 + A sin(2 pi y / wavelength + phase) along the sheet, 2 mm / 0.3
deg noise; ``discover`` fits them jointly.  The figure shows the recovered field along
the sheet with its 1-sigma band against the truth, and the along-sheet residuals of every
shot before and after the extension.

Usage::

    python scripts/example_friction_field.py [--seed 7] [--shots 3] [--amplitude 0.03]
        [-o docs/extend_friction_field.png] [--json REPORT.json]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from discover._world import make_world  # noqa: E402

from curltrack.discover import discover, write_report  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--shots", type=int, default=3)
    ap.add_argument("--amplitude", type=float, default=0.03)
    ap.add_argument("-o", "--out", default="docs/extend_friction_field.png")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(args.seed)
    shots, truth = make_world("friction_field", args.amplitude, rng, n_shots=args.shots)
    c0 = time.process_time()
    rep = discover(shots, seed=args.seed)
    cpu = time.process_time() - c0
    ext = rep.get("extension")
    print(f"truth: amplitude {truth['amplitude']:.3f}, wavelength {truth['wavelength_m']:.3f} m")
    print(f"verdict {rep['verdict']} ({cpu:.0f} s CPU for {len(shots)} shots)")
    if ext:
        print(ext["summary"])
    if args.json:
        write_report(rep, args.json)

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7))
    y = np.linspace(0, max(float(s.data["y"].max()) for s in shots), 400)
    a1.plot(y, 1 + truth["amplitude"] * np.sin(2 * math.pi * y / truth["wavelength_m"]
                                               + truth["phase_rad"]),
            color="k", lw=1.2, label="truth (hidden)")
    if ext:
        f = ext["function"]
        a1.fill_between(f["x"], f["band_lo"], f["band_hi"], color="C3", alpha=0.3, lw=0,
                        label="recovered, 1-sigma band")
        a1.plot(f["x"], f["value"], color="C3", lw=1.2, ls="--", label="recovered")
        a1.set_title(ext["summary"], fontsize=8, loc="left")
    a1.set_xlabel("y along the sheet (m)")
    a1.set_ylabel("friction multiplier")
    a1.legend(fontsize=8, loc="upper right")
    for j, s in enumerate(rep.shot_data):
        use = s.use["y"]
        for fit, style, lab in ((rep.fit0, ".", "baseline"), (rep.best_fit, "o", "extended")):
            r = (s.obs["y"] - fit.predictions[j]["y"])[use] * 1e3
            a2.plot(s.obs["y"][use], r, style, ms=1.5 if style == "." else 1.2,
                    color=f"C{j}", alpha=0.35 if lab == "baseline" else 0.9,
                    label=f"shot {j + 1} {lab}")
    a2.axhline(0, color="k", lw=0.6)
    a2.set_xlabel("y along the sheet (m)")
    a2.set_ylabel("residual in y (mm)")
    a2.legend(fontsize=7, ncol=2, loc="lower left")
    fig.suptitle(f"session of {len(shots)} shots, verdict: {rep['verdict']}", fontsize=10)
    fig.tight_layout()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
