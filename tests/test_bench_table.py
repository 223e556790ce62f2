"""scripts/bench.py: the README table is written from the measured document."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location("bench", ROOT / "scripts" / "bench.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


DOC = {
    "machine": {"platform": "Linux", "python": "3.11", "cpus": 2, "cpu_model": "CPU X",
                "opencv": "5", "decoder_threads": "CURLTRACK_THREADS=1", "load_avg": [0.1]},
    "date": "2026-01-01", "quick": False,
    "simulate": {"draw_ms": 61.0},
    "track": {"speed_540p": {"width": 960, "height": 540, "frames": 150, "threads": 1,
                             "ratio": 0.31, "track_fps": 200.0, "decode_fps": 645.0,
                             "ratio_excl_calibration": 0.4, "calibrate_s": 0.5,
                             "decode_ms": 1.5, "grid_ms": 2.0, "markers_ms": 1.0,
                             "other_ms": 0.5}},
    "batch": {"n_videos": 8, "median_shots_per_min": {"1": 10.0, "2": 16.0}, "speedup": 1.6,
              "load_avg_before": [0.2]},
}


def test_markdown_marks_each_target_by_the_measured_value():
    text = _bench().markdown(DOC)
    lines = {ln.split("|")[1].strip(): ln for ln in text.splitlines() if ln.startswith("| ")}
    assert "61.0 ms" in lines["simulate"] and lines["simulate"].rstrip().endswith("✗ |")
    assert "0.310× decode" in lines["track speed"] and lines["track speed"].endswith("✓ |")
    assert "1.60×" in lines["batch"] and lines["batch"].endswith("✗ |")
    assert "CPU X" in text and "CURLTRACK_THREADS=1" in text


def test_readme_block_is_replaced_and_the_rest_kept(tmp_path):
    bench = _bench()
    readme = tmp_path / "README.md"
    readme.write_text("# title\n\n<!-- BENCHMARKS -->\n\n## next\ntext\n")
    bench.write_readme(readme, "TABLE 1")
    bench.write_readme(readme, "TABLE 2")  # a second run replaces the first table
    src = readme.read_text()
    assert src == "# title\n\n<!-- BENCHMARKS -->\nTABLE 2\n<!-- /BENCHMARKS -->\n\n## next\ntext\n"
