"""Write SHOT.csv / FIT.json / REPORT.json of fixed cases, to compare two versions.

Run it once with the old code on the path and once with the new, then ``--compare``:

    PYTHONPATH=/old/src python scripts/outputs_snapshot.py /tmp/before
    PYTHONPATH=$PWD     python scripts/outputs_snapshot.py /tmp/after
    python scripts/outputs_snapshot.py --compare /tmp/before /tmp/after

Cases: the demo (``scripts/demo.sh``: a draw with a friction patch, rendered with seed 7
under the ladder camera, tracked, fitted, discovered); three rendered and tracked shots
with one effect each (late_curl, pick, ice_slope); simulated series with noise for every
effect (fit + discover), and a two-shot session of opposite spins (ice_slope).  Every
step runs through the command line, as a user would; the comparison is of the files'
text, number by number (their printed digits).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

RIG = Path(__file__).resolve().parent.parent / "fixtures" / "rig.toml"
if not RIG.exists():  # run from a copy outside the repository
    RIG = Path("/work/main/fixtures/rig.toml")

RENDERED = {
    "demo": ("--v0 1.4 --omega0 1.6 --effect friction_patch --param y_start_m=3.5 "
             "--param y_end_m=5.5 --param factor=1.6", "--seed 7 --camera ladder"),
    "late_curl": ("--v0 1.3 --omega0 -1.4 --effect late_curl --param k=0.8",
                  "--seed 3 --camera ladder"),
    "pick": ("--v0 1.3 --omega0 1.5 --effect pick --param t_s=5 --param dvx_m_per_s=0.03",
             "--seed 5 --camera handheld"),
    "ice_slope": ("--v0 1.4 --omega0 1.2 --effect ice_slope --param slope_x_mm_per_m=1.5",
                  "--seed 11 --camera ladder"),
}
NOISE = "--noise-m 0.002 --noise-rad 0.005"
SIMULATED = {
    "sim_vdf": "--v0 1.8 --omega0 1.5 --effect velocity_dependent_friction --param phi=-0.3 "
               "--param alpha=0.008 --seed 1",
    "sim_patch": "--v0 1.9 --omega0 -1.5 --effect friction_patch --param y_start_m=8 "
                 "--param y_end_m=11 --param factor=1.3 --seed 2",
    "sim_late": "--v0 2.0 --omega0 1.8 --effect late_curl --param k=1.0 --seed 3",
    "sim_pick": "--v0 1.9 --omega0 1.4 --effect pick --param t_s=9 --param dvx_m_per_s=0.02 "
                "--seed 4",
    "sim_slope_a": "--v0 1.9 --omega0 1.5 --effect ice_slope --param slope_x_mm_per_m=2 "
                   "--seed 5",
    "sim_slope_b": "--v0 1.8 --omega0 -1.6 --effect ice_slope --param slope_x_mm_per_m=2 "
                   "--seed 6",
    "sim_none": "--v0 1.7 --omega0 1.1 --seed 7",
}


def run(cmd: str, out: Path):
    print("+", cmd, flush=True)
    r = subprocess.run(["curltrack", *cmd.split()], cwd=out, capture_output=True, text=True)
    (out / "log.txt").open("a").write(f"$ {cmd}\n{r.stdout}{r.stderr}exit {r.returncode}\n")


def produce(out: Path, only=None):
    """Run every case into ``out`` (a video already there is not rendered again, a
    tracked shot already there is not tracked again: copy them in to compare only the
    stages after them)."""
    out.mkdir(parents=True, exist_ok=True)
    for name, (sim, ren) in RENDERED.items():
        if only and name not in only:
            continue
        if not (out / f"{name}.mp4").exists():
            run(f"simulate {sim} --rig {RIG} -o {name}_sim.csv", out)
            run(f"render {name}_sim.csv --rig {RIG} -o {name}.mp4 {ren}", out)
        if not (out / f"{name}.csv").exists():  # a tracked shot given: fit and discover it
            run(f"track {name}.mp4 --rig {RIG} -o {name}.csv", out)
        run(f"fit {name}.csv --rig {RIG} -o {name}_fit.json -q", out)
        run(f"discover {name}.csv -o {name}_report.json", out)
    for name, sim in SIMULATED.items():
        if only and name not in only:
            continue
        run(f"simulate {sim} {NOISE} -o {name}.csv", out)
        run(f"fit {name}.csv -o {name}_fit.json -q", out)
        if name != "sim_slope_b":
            run(f"discover {name}.csv -o {name}_report.json", out)
    if not only or "session" in only:
        run("discover sim_slope_a.csv sim_slope_b.csv -o session_report.json", out)


def _walk(a, b, path, out):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k == "version":
                continue
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'after' if k in b else 'before'}")
            else:
                _walk(a[k], b[k], f"{path}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            _walk(x, y, f"{path}[{i}]", out)
    elif a != b and not (isinstance(a, float) and isinstance(b, float)
                         and math.isnan(a) and math.isnan(b)):
        out.append(f"{path}: {a!r} -> {b!r}")


def compare(before: Path, after: Path) -> int:
    n_diff = 0
    for fa in sorted(before.iterdir()):
        if fa.suffix not in (".csv", ".json") or fa.stem.endswith("_sim") \
                or any(k in fa.name for k in (".truth.", ".render.", ".rig.")):
            continue
        fb = after / fa.name
        if not fb.exists():
            print(f"{fa.name}: missing after")
            n_diff += 1
            continue
        if fa.suffix == ".csv":
            same = fa.read_bytes() == fb.read_bytes()
            print(f"{fa.name}: {'identical' if same else 'DIFFERENT'}")
            n_diff += not same
            continue
        diffs: list = []
        _walk(json.loads(fa.read_text()), json.loads(fb.read_text()), fa.stem, diffs)
        print(f"{fa.name}: {'identical' if not diffs else f'{len(diffs)} difference(s)'}")
        for d in diffs[:20]:
            print("   ", d)
        n_diff += bool(diffs)
    return n_diff


if __name__ == "__main__":
    if sys.argv[1] == "--compare":
        sys.exit(1 if compare(Path(sys.argv[2]), Path(sys.argv[3])) else 0)
    produce(Path(sys.argv[1]).resolve(), set(sys.argv[2:]) or None)
