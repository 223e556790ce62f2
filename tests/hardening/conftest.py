"""Session fixtures: a few tiny rendered clips reused by the hardening tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from hardening.badinputs import RIG_TOML, render_clip


@pytest.fixture(scope="session")
def hdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("hardening")


@pytest.fixture(scope="session")
def rig_file(hdir) -> Path:
    p = hdir / "rig.toml"
    p.write_text(RIG_TOML)
    return p


@pytest.fixture(scope="session")
def good_clip(hdir):
    """(video, truth Series, Rig): a 1.6 s ladder draw at 480x270."""
    return render_clip(hdir / "good.mp4", seed=11)


@pytest.fixture(scope="session")
def wide_clip(hdir):
    """640x360 with the principal point at the centre and no tilt/distortion: turning its
    frames about their centre is exactly a camera turning about its optical axis."""
    return render_clip(hdir / "wide.mp4", size=(640, 360), view_m=1.6, seed=12, k1=0.0,
                       tilt_deg=0.0, centred=True)


class Cli:
    """Run the real typer app in-process; check the contract's failure shape."""

    def __init__(self):
        self.runner = CliRunner()

    def __call__(self, *args):
        from curltrack.cli import app

        res = self.runner.invoke(app, [str(a) for a in args])
        if res.exception is not None and not isinstance(res.exception, SystemExit):
            raise res.exception  # a traceback is a defect: let the test show it
        return res

    def fails(self, *args, output: Path | None = None, names=()):
        """Exit 1, exactly one stderr line naming ``names``; no file under ``output``."""
        res = self(*args)
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        assert res.exit_code == 1, (res.exit_code, res.stdout, res.stderr)
        assert len(lines) == 1, lines
        line = lines[0]
        assert line.startswith("curltrack: error: "), line
        for n in names:
            assert str(n) in line, (n, line)
        assert "Traceback" not in res.stderr and "internal error" not in line, line
        if output is not None:
            assert not Path(output).exists(), f"{output} left behind after a failure"
            stray = [p for p in Path(output).parent.glob(f".{Path(output).stem}.*")]
            assert not stray, stray
        return line

    def succeeds(self, *args):
        res = self(*args)
        assert res.exit_code == 0, (res.exit_code, res.stdout, res.stderr)
        return res


@pytest.fixture(scope="session")
def cli() -> Cli:
    return Cli()
