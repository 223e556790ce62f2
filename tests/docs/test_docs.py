"""The user docs (docs/*.md) are true: every documented key and column is what the code
writes, both ways, and the documented example rig renders and tracks."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
SHOT_COLUMNS = {"frame", "t", "x", "y", "theta", "ok"}


def tables(doc: str) -> dict[str, list[dict]]:
    """``<!-- table: NAME -->`` + the markdown table after it -> rows as dicts."""
    text = (DOCS / doc).read_text()
    out = {}
    for m in re.finditer(r"<!-- table: ([\w.]+) -->\n((?:\|.*\n)+)", text):
        lines = [ln.strip().strip("|") for ln in m.group(2).strip().splitlines()]
        head = [h.strip() for h in lines[0].split("|")]
        rows = [dict(zip(head, (c.strip() for c in ln.split("|")))) for ln in lines[2:]]
        out[m.group(1)] = rows
    return out


def names(cell: str) -> list[str]:
    """Backticked names of a cell: "`u_px`, `v_px`" -> ["u_px", "v_px"]."""
    return re.findall(r"`([^`]+)`", cell)


def documented(doc, table, col="written by", where=None) -> set[str]:
    rows = tables(doc)[table]
    first = next(iter(rows[0]))
    return {n for r in rows
            if where is None or set(where) & {w.strip() for w in r.get(col, "").split(",")}
            for n in names(r[first])}


def example_rig_text() -> str:
    return re.search(r"```toml\n(.*?)```", (DOCS / "rig.md").read_text(), re.S).group(1)


def cli(*args, cwd):
    proc = subprocess.run([sys.executable, "-m", "curltrack", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True)
    assert proc.returncode == 0, f"curltrack {' '.join(map(str, args))}: {proc.stderr}"
    return proc


# -- the rig file and the effects: against the code's own tables ------------------------

def test_rig_doc_lists_every_key_with_its_default_and_range():
    from curltrack import rig as rigmod

    rows = tables("rig.md")["rig"]
    doc = {names(r["key"])[0]: r for r in rows}
    code = {(f"[[{s}]]" if s == "markers" else f"[{s}]") + f".{k}"
            for s, keys in rigmod._ALLOWED.items() for k in keys}
    assert set(doc) == code, f"documented only: {set(doc) - code}; code only: {code - set(doc)}"
    defaults = rigmod.Rig()
    attr = {"[grid].depth_m": "grid_depth_m", "[rock].band_radius_m": "band_radius_m",
            "[rock].inertia_radius_m": "inertia_radius_m"}
    for key, row in doc.items():
        section, name = key.strip("[]").replace("]]", "").replace("]", "").split(".")
        rng = rigmod._RANGES.get(f"{section}.{name}")
        if rng is not None:
            lo, hi = (float(v) for v in row["range"].replace("−", "-").split("–"))
            assert (lo, hi) == rng, f"{key}: documented range {lo}-{hi}, code {rng}"
        else:
            assert row["range"] == "—", key
        if key in attr:
            assert float(row["default"]) == getattr(defaults, attr[key]), key
        elif row["default"] == "required":
            data = tomllib_example()
            table = data[section][0] if section == "markers" else data[section]
            table.pop(name)
            with pytest.raises(Exception, match="missing required"):
                rigmod.rig_from_dict(data)


def test_rig_doc_lists_every_tracking_setting():
    """docs/rig.md's [tracking] table is TrackingSettings: keys, units, defaults, ranges."""
    from curltrack.settings import describe_settings

    doc = {names(r["key"])[0]: r for r in tables("rig.md")["tracking"]}
    code = {r["key"]: r for r in describe_settings()}
    assert set(doc) == set(code), (f"documented only: {set(doc) - set(code)}; "
                                   f"code only: {set(code) - set(doc)}")
    for key, row in doc.items():
        assert float(row["default"]) == code[key]["default"], key
        assert row["unit"] == code[key]["unit"], key
        lo, hi = (float(v) for v in row["range"].replace("−", "-").split("–"))
        assert (lo, hi) == tuple(map(float, code[key]["range"])), key
        assert row["why this default"], key


def tomllib_example() -> dict:
    import tomllib

    return tomllib.loads(example_rig_text())


def test_effects_doc_lists_every_parameter_with_its_default():
    from curltrack.physics.effects import effect_parameters, EFFECTS

    rows = tables("commands.md")["effects"]
    doc = {(names(r["effect"])[0], names(r["parameter"])[0]): r for r in rows}
    code = {(e, p) for e in EFFECTS for p in effect_parameters(e)}
    assert set(doc) == code, f"documented only: {set(doc) - code}; code only: {code - set(doc)}"
    for (e, p), row in doc.items():
        default = effect_parameters(e)[p]
        if default == "required" or default is None:
            assert row["default"] in ("required", "the model's"), (e, p)
        else:
            assert float(row["default"]) == default, (e, p, row["default"], default)


def test_docs_links_resolve_and_readme_points_to_docs():
    """Every relative link (and #anchor) in README and docs/ exists; no ../shared."""
    readme = (ROOT / "README.md").read_text()
    assert "../shared" not in readme and "shared/contract" not in readme
    for doc in ("rig.md", "files.md", "commands.md", "filming.md", "review.md"):
        assert f"docs/{doc}" in readme or "(docs/README.md)" in readme, doc

    def slug(title):
        return re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")

    for md in [ROOT / "README.md", *DOCS.glob("*.md")]:
        for target in re.findall(r"\]\(([^)\s]+)\)", md.read_text()):
            if re.match(r"\w+://", target):
                continue
            file, _, anchor = target.partition("#")
            dest = (md.parent / file).resolve() if file else md
            assert dest.exists(), f"{md.name}: broken link {target}"
            if anchor and dest.suffix == ".md":
                heads = {slug(h) for h in re.findall(r"^#+ (.*)$", dest.read_text(), re.M)}
                assert anchor in heads, f"{md.name}: no heading #{anchor} in {dest.name}"


# -- the output files: run every command on tiny inputs and compare both ways -----------

@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """The documented example rig -> simulate -> render -> track (CLI), fit, discover."""
    from curltrack.physics.shot import ShotModel
    from curltrack.render import RenderConfig, render_video
    from curltrack.rig import load_rig
    from curltrack.simulate import simulate_series

    seed = int(np.random.SeedSequence().entropy % 2**31)
    rng = np.random.default_rng(seed)
    tmp = tmp_path_factory.mktemp("docs")
    (tmp / "rig.toml").write_text(example_rig_text())
    rig = load_rig(tmp / "rig.toml")
    v0, w0 = rng.uniform(0.45, 0.6), rng.choice([-1, 1]) * rng.uniform(0.8, 1.6)
    sim = simulate_series(ShotModel(v0=v0, omega0=w0, alpha_y=0.03), fps=30)
    render_video(sim, rig, tmp / "shot.mp4", tmp / "truth.csv",
                 config=RenderConfig(blur_subframes=2), seed=seed)
    cli("track", "shot.mp4", "--rig", "rig.toml", "-o", "shot.csv", "-q", cwd=tmp)
    # a series with a pick, so that discovery refits a candidate
    cli("simulate", "--v0", "0.8", "--omega0", "1.5", "--effect", "pick", "--param", "t_s=2",
        "--param", "dvx_m_per_s=0.02", "--noise-m", "0.002", "--noise-rad", "0.005",
        "--seed", seed, "-o", "sim.csv", cwd=tmp)
    cli("fit", "sim.csv", "-o", "fit.json", cwd=tmp)
    cli("export", "shot.csv", "--derivatives", "-o", "shot_v.csv", cwd=tmp)
    cli("discover", "sim.csv", "-o", "report.json", cwd=tmp)
    return tmp, seed, (v0, w0)


def _json(path):
    return json.loads(Path(path).read_text())


def test_shot_csv_columns(outputs):
    tmp, seed, _ = outputs
    track_cols = set(pd.read_csv(tmp / "shot.csv").columns)
    sim_cols = set(pd.read_csv(tmp / "sim.csv").columns)
    assert track_cols == documented("files.md", "shot.csv", where={"all", "track"})
    assert sim_cols == documented("files.md", "shot.csv", where={"all", "simulate"})
    truth_cols = set(pd.read_csv(tmp / "truth.csv").columns) - SHOT_COLUMNS
    n_markers = len(tomllib_example()["markers"])
    doc = {n.replace("<i>", str(i)) for n in documented("files.md", "truth.csv")
           for i in range(n_markers)}
    assert truth_cols == doc  # (this render writes none of the optional columns)
    optional = {n for r in tables("files.md")["truth.csv.optional"] for n in names(r["column"])}
    assert not optional & doc


def test_export_columns(outputs):
    tmp, _, _ = outputs
    added = set(pd.read_csv(tmp / "shot_v.csv").columns) - set(pd.read_csv(tmp / "shot.csv").columns)
    assert added == documented("review.md", "export")


def test_sidecar_keys(outputs):
    tmp, seed, _ = outputs
    written = {"track": set(_json(tmp / "shot.json")), "simulate": set(_json(tmp / "sim.json")),
               "render": set(_json(tmp / "truth.json")),
               "export": set(_json(tmp / "shot_v.json"))}
    for who, keys in written.items():
        need = documented("files.md", "shot.json", where={"all", who})
        assert need <= keys, f"{who} does not write documented {need - keys}"
    every = documented("files.md", "shot.json")
    extra = set().union(*written.values()) - every
    assert not extra, f"SHOT.json keys written but not documented in docs/files.md: {extra}"


def test_fit_json_keys(outputs):
    tmp, _, _ = outputs
    rows = tables("files.md")["fit.json"]
    doc = {names(r["key"])[0] for r in rows}
    doc |= {names(r["key"])[0] + "_err" for r in rows if r["1σ"] == "✓"}
    written = set(_json(tmp / "fit.json"))
    assert written == doc, f"undocumented: {written - doc}; not written: {doc - written}"


def test_report_json_keys(outputs):
    tmp, _, _ = outputs
    rep = _json(tmp / "report.json")
    assert set(rep) == documented("files.md", "report.json", "written")
    assert set(rep["baseline"]) == documented("files.md", "report.baseline", "written")
    every = documented("files.md", "report.finding", "written")
    need = documented("files.md", "report.finding", "written", {"always", "candidate"})
    refitted = 0
    for f in rep["findings"]:
        assert set(f) <= every, f"undocumented finding keys {set(f) - every}"
        if f["effect"] != "unexplained":
            assert need <= set(f), f"{f['effect']}: missing {need - set(f)}"
            refitted += "structure_after" in f
    assert refitted, "no candidate was refitted: the finding table's 'refitted' rows untested"


def test_documented_example_rig_renders_and_tracks(outputs):
    """From the docs alone: the example rig, a rendered shot, tracked against truth."""
    tmp, seed, (v0, w0) = outputs
    shot = pd.read_csv(tmp / "shot.csv")
    truth = pd.read_csv(tmp / "truth.csv")
    m = shot.merge(truth[["frame", "x", "y", "theta"]], on="frame", suffixes=("", "_t"))
    ok = m["ok"] == 1
    err = np.hypot(m.x - m.x_t, m.y - m.y_t)[ok]
    msg = f"seed {seed}, v0 {v0:.3f} m/s, omega0 {w0:.3f} rad/s"
    assert ok.mean() > 0.9, msg
    assert np.sqrt(np.mean(err ** 2)) < 2e-3, msg
    assert np.degrees(np.sqrt(np.mean((m.theta - m.theta_t)[ok] ** 2))) < 0.5, msg


def test_exit_statuses_are_as_documented(tmp_path):
    rows = {r["status"] for r in tables("commands.md")["exit"]}
    assert {"0", "1", "2"} <= rows
    run = [sys.executable, "-m", "curltrack"]
    usage = subprocess.run(run + ["fit", "--bogus"], capture_output=True, text=True)
    bad = subprocess.run(run + ["fit", str(tmp_path / "missing.csv"), "-o",
                                str(tmp_path / "f.json")], capture_output=True, text=True)
    assert usage.returncode == 2
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1
    assert bad.stderr.startswith("curltrack: error: ") and "missing.csv" in bad.stderr
