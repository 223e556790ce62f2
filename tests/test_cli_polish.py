"""Small command-line defects stay fixed: a closed pipe, flags in --help, render's rest."""

import subprocess
import sys

import numpy as np
import pandas as pd

RUN = [sys.executable, "-m", "curltrack"]


def test_output_piped_into_head_is_not_an_error(tmp_path):
    subprocess.run(RUN + ["simulate", "--v0", "1", "--omega0", "1", "--noise-m", "0.002",
                          "-o", str(tmp_path / "s.csv")], check=True, capture_output=True)
    cmd = " ".join(RUN + ["fit", str(tmp_path / "s.csv"), "-o", str(tmp_path / "f.json")])
    p = subprocess.run(f"set -o pipefail; {cmd} | head -1", shell=True, executable="/bin/bash",
                       capture_output=True, text=True)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert p.stdout.startswith("shot type") and (tmp_path / "f.json").exists()


def test_help_shows_no_type_after_plain_flags():
    out = subprocess.run(RUN + ["fit", "--help"], capture_output=True, text=True,
                         env={"COLUMNS": "100", "PATH": "/usr/bin:/bin"}).stdout
    flags = [ln for ln in out.splitlines() if "--quiet" in ln or "--fixed-stop" in ln]
    assert len(flags) == 2 and not any("<bool>" in ln for ln in flags), flags
    assert "<path>" in out  # options that take a value still say what


def test_render_from_initial_conditions_shows_the_rock_at_rest(tmp_path):
    rng = np.random.default_rng()
    v0 = rng.uniform(0.2, 0.35)
    p = subprocess.run(RUN + ["render", "--v0", f"{v0:.3f}", "--omega0", "1", "-o",
                              str(tmp_path / "v.mp4"), "--truth", str(tmp_path / "t.csv"),
                              "--width", "96", "--height", "64", "--blur-subframes", "1"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert p.stderr == "", p.stderr  # no progress output when stderr is not a terminal
    truth = pd.read_csv(tmp_path / "t.csv")
    import json

    meta = json.loads((tmp_path / "t.json").read_text())
    rest = truth["t"].iloc[-1] - max(meta["t_stop_translation"], meta["t_stop_rotation"])
    assert rest > 0.9, f"v0 {v0:.3f}: the video ends {rest:.3f} s after the stop"


def test_progress_bar_runs_on_a_terminal_and_is_silent_otherwise(capsys):
    from curltrack.progress import progress_bar

    with progress_bar("x", 3) as advance:  # pytest's stderr is not a terminal
        for _ in range(3):
            advance()
    assert capsys.readouterr().err == ""
    with progress_bar("x", 3, enabled=True) as advance:
        for _ in range(3):
            advance()
