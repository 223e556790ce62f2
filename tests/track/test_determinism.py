"""The same input gives the same output: a rendered H.264 clip and its track, each made
twice in separate processes (other hash seeds, heap contents and thread counts), are
byte-identical.

(libx264's macroblock tree read memory it had not written at 720 and 960 px widths: the
same frames gave another file in about half the runs, and a phone test's seed passed or
failed with it - see :data:`curltrack.render.encode.X264_PARAMS`.  Two BLAS threads moved
a tracked phone clip's y by 0.6 mm - see :func:`curltrack.track.track_video`.)"""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

import curltrack

#: Renders a clip: ``python -c RENDER seed path`` (960x540 H.264: a width that is not a
#: multiple of 128 px, where the encoder's uninitialised reads showed).
RENDER = """
import sys
import numpy as np
from clips import render_clip
from curltrack.render.encode import EncodingConfig
rng = np.random.default_rng(int(sys.argv[1]))
enc = EncodingConfig("h264", bitrate_bps=float(rng.uniform(1e6, 4e6)))
render_clip(sys.argv[2], rng, n_frames=30, width=960, height=540, encoding=enc)
"""


def _run(args, cwd, run: int):
    """Run ``python args`` in ``cwd`` with a run-specific hash seed, heap contents
    (glibc's MALLOC_PERTURB_ fills every new and freed block with a run's own byte) and
    ``run`` threads (decoder, OpenCV, BLAS - as far as each allows)."""
    root = Path(curltrack.__file__).resolve().parents[1]
    threads = {name: str(run) for name in ("CURLTRACK_THREADS", "OMP_NUM_THREADS",
                                           "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    env = dict(os.environ, **threads, PYTHONHASHSEED=str(run), MALLOC_PERTURB_=str(85 * run),
               MALLOC_MMAP_THRESHOLD_="1000000000",  # (large blocks from the heap too)
               PYTHONPATH=os.pathsep.join([str(root), str(root / "tests"),
                                           os.environ.get("PYTHONPATH", "")]))
    p = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]


def test_same_clip_same_bytes_in_other_processes(tmp_path):
    """Render and track twice, each in its own processes, on 1 and on 2 threads: the
    video, the series CSV and its sidecar JSON are the same bytes."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    outputs = []
    for run in (1, 2):
        _run(["-c", RENDER, str(seed), "clip.mp4"], tmp_path, run)
        _run(["-m", "curltrack", "track", "clip.mp4", "--rig", "clip.rig.toml",
              "-o", "shot.csv"], tmp_path, run)
        outputs.append({name: (tmp_path / name).read_bytes()
                        for name in ("clip.mp4", "shot.csv", "shot.json")})
        for name in outputs[-1]:  # (the second run writes them anew)
            (tmp_path / name).unlink()
    for name, data in outputs[0].items():
        assert outputs[1][name] == data, f"seed {seed}: {name} differs between runs"
