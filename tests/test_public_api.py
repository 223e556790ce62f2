"""The public API: ``from curltrack import ...`` gives the stages' own functions (real
signatures, numpydoc with Examples), and the Python API page's worked example prints
what the page says."""

import contextlib
import inspect
import io
import re
from pathlib import Path

import pytest

import curltrack

DOC = Path(__file__).resolve().parent.parent / "docs" / "python-api.md"
FUNCTIONS = ("read_series", "write_series", "calibrate_frame", "track_video", "fit_series",
             "simulate_series", "discover", "write_report", "render", "run_batch")


@pytest.mark.parametrize("name", FUNCTIONS)
def test_public_functions_have_real_signatures_and_examples(name):
    f = getattr(curltrack, name)
    assert name in curltrack.__all__
    params = inspect.signature(f).parameters
    assert not any(p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in params.values()), \
        f"{name}{inspect.signature(f)}"
    doc = inspect.getdoc(f)
    for section in ("Parameters", "Returns", "Examples"):
        assert f"\n{section}\n---" in doc, (name, section)


def test_function_names_stay_functions_after_their_packages_are_imported():
    import curltrack.discover.results  # noqa: F401  (binds the sub-package on curltrack)
    import curltrack.render.config  # noqa: F401
    from curltrack.discover import discover

    assert curltrack.discover is discover and callable(curltrack.render)


def test_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        curltrack.nope  # noqa: B018


@pytest.mark.slow
def test_worked_example_prints_what_the_page_says():
    text = DOC.read_text()
    code, expected = re.search(r"```python\n(.*?)```.*?```\n(.*?)```", text, re.S).groups()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, str(DOC), "exec"), {})
    assert out.getvalue() == expected
