"""Run the suite's randomly seeded tests again and again, and list their rare failures.

    python scripts/farm_seeds.py [--rounds N | --minutes M] [--workers W] [--out DIR]
                                 [-k EXPR] [--slow]

The suite draws its set-ups from fresh entropy (``np.random.SeedSequence()``) in every
run, so each run tries new cases and a draw that fails 1 time in 200 shows up in CI
one day.  This script finds those draws before CI does: it collects the test functions
that draw a seed (in their body, or through a fixture of their file or of
``tests/conftest.py`` that does), runs them round after round with pytest, and writes
every failure with its seed and the command that replays it
(``CURLTRACK_TEST_SEED=<seed> pytest <test>``) to ``DIR/failures.jsonl``, plus a summary
table to ``DIR/summary.md``.  Slow-marked tests are left out unless ``--slow``.

Exit status: 0 when every round passed, 1 when any test failed, 2 on a usage error.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DRAW = "SeedSequence()"
SEED = re.compile(r"seed[\s=:]*(\d{3,})", re.IGNORECASE)


def _is_fixture(node: ast.FunctionDef) -> bool:
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        if "fixture" in ast.unparse(target):
            return True
    return False


def _functions(path: Path):
    src = path.read_text()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.FunctionDef):
            yield node, ast.get_source_segment(src, node) or ""


def seeded_tests(tests: Path) -> list[str]:
    """Node ids (``path::name``, relative to the repository) of the test functions that
    draw a seed themselves or through one of their fixtures."""
    shared = {n.name for n, seg in _functions(tests / "conftest.py")
              if _is_fixture(n) and DRAW in seg} if (tests / "conftest.py").exists() else set()
    ids = []
    for path in sorted(tests.rglob("test_*.py")):
        funcs = list(_functions(path))
        drawing = shared | {n.name for n, seg in funcs if _is_fixture(n) and DRAW in seg}
        for node, seg in funcs:
            if not node.name.startswith("test_") or _is_fixture(node):
                continue
            args = {a.arg for a in node.args.args}
            if DRAW in seg or args & drawing:
                ids.append(f"{path.relative_to(ROOT)}::{node.name}")
    return ids


def failures(junit: Path) -> list[dict]:
    """Failed and erroring test cases of a JUnit XML report: id, seed, message."""
    out = []
    for case in ET.parse(junit).getroot().iter("testcase"):
        for bad in list(case.findall("failure")) + list(case.findall("error")):
            text = (bad.get("message") or "") + "\n" + (bad.text or "")
            seed = SEED.search(text)
            path = case.get("file") or case.get("classname", "").replace(".", "/") + ".py"
            out.append(dict(test=f"{path}::{case.get('name')}",
                            seed=int(seed.group(1)) if seed else None,
                            message=(bad.get("message") or "").splitlines()[0][:300]
                            if bad.get("message") else ""))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=None, help="rounds to run (default 3)")
    ap.add_argument("--minutes", type=float, default=None,
                    help="run rounds until this much time has passed")
    ap.add_argument("--workers", type=int, default=1, help="pytest-xdist workers")
    ap.add_argument("--out", type=Path, default=ROOT / "farm-results")
    ap.add_argument("-k", dest="keyword", default=None, help="pytest -k expression")
    ap.add_argument("--slow", action="store_true", help="include slow-marked tests")
    a = ap.parse_args(argv)
    if a.rounds is not None and a.minutes is not None:
        ap.error("give --rounds or --minutes, not both")
    rounds = a.rounds if a.rounds is not None else (None if a.minutes else 3)
    ids = seeded_tests(ROOT / "tests")
    if not ids:
        print("no seeded tests found under tests/", file=sys.stderr)
        return 2
    a.out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    env.pop("CURLTRACK_TEST_SEED", None)   # fresh draws, never a replay
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
    # (the project's addopts deselect slow tests: a later -m overrides them)
    cmd += ["-m", "slow or not slow" if a.slow else "not slow"]
    if a.workers > 1:
        cmd += ["-n", str(a.workers)]
    if a.keyword:
        cmd += ["-k", a.keyword]
    print(f"{len(ids)} seeded test functions; results in {a.out}", flush=True)
    found, k, t_start = [], 0, time.time()
    log = a.out / "failures.jsonl"
    while True:
        k += 1
        junit = a.out / f"round{k:03d}.xml"
        t0 = time.time()
        r = subprocess.run([*cmd, f"--junitxml={junit}", *ids], cwd=ROOT, env=env,
                           capture_output=True, text=True)
        (a.out / f"round{k:03d}.log").write_text(r.stdout + r.stderr)
        got = failures(junit) if junit.exists() else []
        if r.returncode not in (0, 1, 5) and not got:
            got = [dict(test="(pytest)", seed=None, message=f"exit {r.returncode}")]
        with log.open("a") as fh:
            for f in got:
                f["round"] = k
                f["replay"] = (f"CURLTRACK_TEST_SEED={f['seed']} " if f["seed"] else "") + \
                    f"python -m pytest -p no:cacheprovider '{f['test']}'"
                fh.write(json.dumps(f) + "\n")
        found += got
        tail = (r.stdout.strip().splitlines() or [""])[-1]
        print(f"round {k}: {tail} ({time.time() - t0:.0f} s)", flush=True)
        if rounds is not None and k >= rounds:
            break
        if a.minutes is not None and time.time() - t_start > 60 * a.minutes:
            break
    lines = ["| round | test | seed | message |", "|---|---|---|---|"]
    lines += [f"| {f['round']} | `{f['test']}` | {f['seed']} | {f['message'][:120]} |"
              for f in found]
    (a.out / "summary.md").write_text(
        f"{k} round(s) of {len(ids)} seeded test functions: {len(found)} failure(s)\n\n"
        + ("\n".join(lines) + "\n" if found else ""))
    print(f"{k} round(s): {len(found)} failure(s)" + (f" - see {log}" if found else ""))
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
