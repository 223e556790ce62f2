"""Imports point down the data flow: video -> calib -> track -> series -> fit / discover.

Read from the source (every ``import``, also inside functions), so a lazy import that
reaches up or across a layer is caught too.
"""

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parent.parent / "curltrack"

#: module or sub-package -> the parts of curltrack it must not import
FORBIDDEN = {
    "physics": {"video", "calib", "track", "series", "fit", "discover", "simulate", "render",
                "batch", "cli", "plots", "doctor", "fitting"},
    # the one least-squares layer, below fit and discover
    "fitting.py": {"video", "calib", "track", "series", "fit", "discover", "simulate",
                   "render", "batch", "cli", "plots", "doctor"},
    # the lowest module: statistics every stage uses
    "_stats.py": {"video", "calib", "track", "series", "fit", "discover", "simulate",
                  "render", "batch", "cli", "plots", "doctor", "physics", "rig", "settings"},
    "series": {"video", "calib", "track", "fit", "discover", "simulate", "render", "batch",
               "cli", "plots", "doctor"},
    "fit.py": {"video", "calib", "track", "discover", "render", "batch", "cli"},
    "discover": {"video", "calib", "track", "render", "batch", "cli"},
    "simulate.py": {"video", "calib", "track", "fit", "discover", "render", "batch", "cli"},
}


def _imports(path: Path):
    """Top-level curltrack parts imported by ``path`` (relative imports resolved)."""
    rel = path.relative_to(PKG.parent).with_suffix("").parts  # ("curltrack", "discover", "x")
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(rel[:-node.level])
                parts = base + (node.module.split(".") if node.module else [])
                if len(parts) == 1:  # "from .. import x": x are the parts
                    for a in node.names:
                        yield a.name, node.lineno
                    continue
            else:
                parts = (node.module or "").split(".")
            if parts[0] == "curltrack" and len(parts) > 1:
                yield parts[1], node.lineno
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] == "curltrack" and len(parts) > 1:
                    yield parts[1], node.lineno


@pytest.mark.parametrize("layer", sorted(FORBIDDEN))
def test_imports_point_down_the_data_flow(layer):
    target = PKG / layer
    files = [target] if target.suffix == ".py" else sorted(target.rglob("*.py"))
    bad = [f"{f.relative_to(PKG.parent)}:{line} imports curltrack.{part}"
           for f in files for part, line in _imports(f)
           if part.removesuffix(".py") in FORBIDDEN[layer]]
    assert not bad, "\n".join(bad)
