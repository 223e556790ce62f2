"""Discovery on data we did not make: other instruments' noise, position-only series,
irregular sampling, sessions with per-shot friction spread (issue 18).

Clean shots (the baseline world + noise of one class) must give ``none``; set-ups and
seeds are drawn here from fresh entropy, which is printed in every assertion message.
"""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from curltrack.cli import app
from curltrack.discover import discover
from curltrack.instrument import (ALL_NOISE_CLASSES, NOISE_CLASSES, TYPICAL_SCALE, Sampling,
                                  session_models)
from curltrack.physics import ShotModel
from curltrack.series import write_series
from curltrack.simulate import simulate_series

runner = CliRunner()


def _entropy() -> int:
    return int(np.random.SeedSequence().entropy % (1 << 63))


def clean_case(rng, noise_class, rate_hz, theta, n_shots=1):
    """A clean single shot or session: paper model (defaults: the paper's draw), noise
    of ``noise_class`` at its typical scale, ``rate_hz`` with jitter, a gap and a first
    row up to 1 s after release below 30 Hz."""
    sm, sr = TYPICAL_SCALE[noise_class]
    base = ShotModel(v0=rng.uniform(1.4, 2.2), omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 3))
    models = [base] if n_shots == 1 else session_models(base, n_shots, rng)
    irregular = rate_hz < 30
    sampling = Sampling(rate_hz=rate_hz, jitter_s=0.1 / rate_hz if irregular else 0.0,
                        start_s=float(rng.uniform(0, 1)) if irregular else 0.0,
                        n_gaps=int(irregular))
    return [simulate_series(m, noise_m=sm, noise_rad=sr, noise_class=noise_class,
                            seed=int(rng.integers(1 << 30)), theta_measured=theta,
                            sampling=sampling) for m in models]


#: the rates issue 18 names: an instrument's 10 Hz, PAL 25/50, NTSC/phone 30/60 (below 30
#: Hz with timestamp jitter, a gap and a late first row - :func:`clean_case`).  Session 45,
#: 30 clean shots per class and rate at 25, 50 and 60 Hz: white 0/90, AR(1) 1/90 (an
#: `extended` at 25 Hz), heavy 0/90, tracked 0/90; step noise at 10 Hz 1/80.
RATES_HZ = (10.0, 25.0, 30.0, 50.0, 60.0)


def _false_alarms(noise_class, n_cases, seed, sessions=False, rates=RATES_HZ):
    rng = np.random.default_rng(seed)
    bad = []
    for i in range(n_cases):
        rate = float(rng.choice(rates))
        theta = bool(rng.random() < 0.5) if noise_class != "steps" else bool(rng.random() < 0.3)
        n_shots = int(rng.integers(3, 9)) if sessions else 1
        rep = discover(clean_case(rng, noise_class, rate, theta, n_shots), n_boot=200,
                       seed=int(rng.integers(1 << 30)))
        if rep["verdict"] != "none":
            bad.append((i, rate, theta, n_shots, rep["verdict"]))
    return bad


@pytest.mark.parametrize("noise_class", ALL_NOISE_CLASSES)
def test_clean_shots_give_none_under_each_noise_class(noise_class):
    """Fast version: 2 clean single shots per class (at a rate of :data:`RATES_HZ`, with
    or without theta), the slow tests' set-up; the issue's four classes and two more (a vibrating
    camera, values rounded to a centimetre).  With a false-alarm rate of <= 5 % two
    alarms in two cases happen < 0.3 % of runs.  (Under step noise at 10 Hz alone the
    rate was above that until session 17 - 10/160, now 4/160, README - and two 10 Hz
    shots alarmed together in 2 of ~8 CI runs, seeds 4868596420914615096 and
    443372549474165855; 1 of 80 fresh 10 Hz step-noise shots in session 45.)"""
    seed = _entropy()
    bad = _false_alarms(noise_class, 2, seed)
    assert len(bad) <= 1, f"seed {seed}: {bad}"


@pytest.mark.slow
@pytest.mark.parametrize("noise_class", ALL_NOISE_CLASSES)
def test_false_alarm_rate_per_noise_class(noise_class):
    """>= 40 clean single shots per class: <= 5 % (2 of 40) say anything but none."""
    seed = _entropy()
    bad = _false_alarms(noise_class, 40, seed)
    assert len(bad) <= 2, f"seed {seed}: {len(bad)}/40 false alarms: {bad}"


@pytest.mark.slow
@pytest.mark.parametrize("noise_class", NOISE_CLASSES)
def test_false_alarm_rate_sessions(noise_class):
    """40 sessions of 3-8 shots with a 5 % per-shot alpha spread: <= 5 % (2 of 40) say
    anything but none."""
    seed = _entropy()
    bad = _false_alarms(noise_class, 40, seed, sessions=True)
    assert len(bad) <= 2, f"seed {seed}: {len(bad)}/40 false alarms: {bad}"


def test_session_of_default_shots_is_none():
    """Three shots simulated with `simulate`'s defaults (a tied rotation law, so each
    shot's alpha_theta differs), each `none` alone, are `none` together too, and no
    baseline parameter sits at a bound.  Two sessions, at most one false alarm (the
    candidates' 1 % look-elsewhere levels make one in a few per cent by design)."""
    seed = _entropy()
    rng = np.random.default_rng(seed)
    alarms = []
    for _ in range(2):
        shots = [simulate_series(ShotModel(v0=float(rng.uniform(1.5, 2.1)),
                                           omega0=float(rng.choice([-1, 1])
                                                        * rng.uniform(1, 2.5))),
                                 noise_m=0.002, noise_rad=0.005,
                                 seed=int(rng.integers(1 << 30)))
                 for _ in range(3)]
        rep = discover(shots, n_boot=200, seed=int(rng.integers(1 << 30)))
        assert not any("at its bound" in w for w in rep["warnings"]), (seed, rep["warnings"])
        if rep["verdict"] != "none":
            alarms.append((rep["verdict"], rep["warnings"]))
    assert len(alarms) <= 1, (seed, alarms)


def test_position_only_10hz_clockwise_draw_is_none():
    """A 10 Hz x, y series of a clockwise draw, first row 1 s after release: `none`,
    the spin side read off the curl (clockwise), no spin impulse among the candidates.
    Two draws, at most one false alarm (as above); side and impulse on every draw."""
    seed = _entropy()
    rng = np.random.default_rng(seed)
    alarms = []
    for _ in range(2):
        m = ShotModel(v0=float(rng.uniform(1.5, 2.2)), omega0=-float(rng.uniform(0.8, 3.0)))
        s = simulate_series(m, noise_m=0.002, seed=int(rng.integers(1 << 30)),
                            theta_measured=False,
                            sampling=Sampling(rate_hz=10, jitter_s=0.003, start_s=1.0))
        rep = discover(s, n_boot=200, seed=int(rng.integers(1 << 30)))
        if rep["verdict"] != "none":
            alarms.append(rep["verdict"])
        assert rep["shots"][0]["spin"] == -1, seed
        pick = next(f for f in rep["findings"] if f["effect"] == "pick")
        assert "domega_rad_per_s" not in pick["params"], seed
        assert "ice_slope" in rep["not_tested"]
    assert len(alarms) <= 1, (seed, alarms)


def test_position_only_spin_that_stops_first_is_fitted_not_named():
    """Position-only draws whose spin stops at a random 40-85 % of the slide (the curl
    ends with it) at 10 or 30 Hz: `none`, not a late curl or a pick, and the curl's end
    reported within 3 sigma (or 0.3 s) of the truth.  Two draws, at most one false
    alarm: each candidate's threshold is a 1 % look-elsewhere level, so one draw says
    something other than `none` in a few per cent of runs by design (a 10 Hz draw named
    a pick at delta-BIC 5.6, seed 2781979112140719912); two in two, < 0.3 %."""
    import re

    from curltrack.physics import closed_form as cf

    seed = _entropy()
    rng = np.random.default_rng(seed)
    alarms = []
    for _ in range(2):
        m = ShotModel(v0=float(rng.uniform(1.5, 2.2)), omega0=1.0)
        alpha_theta = m.alpha_theta_value      # (the rotation law's, held below)
        t_tr = cf.stop_time_translation(m.v0, m.phi_y, m.alpha_y)
        t_rot = float(rng.uniform(0.4, 0.85)) * t_tr
        unit = cf.stop_time_rotation(1.0, m.phi_theta, alpha_theta)
        w0 = float(rng.choice([-1, 1])) * (t_rot / unit) ** (1.0 / (1.0 - m.phi_theta))
        m = ShotModel(v0=m.v0, omega0=w0, alpha_theta=alpha_theta)
        rate = float(rng.choice([10.0, 30.0]))
        s = simulate_series(m, noise_m=0.002, seed=int(rng.integers(1 << 30)),
                            theta_measured=False, sampling=Sampling(rate_hz=rate))
        rep = discover(s, n_boot=200, seed=int(rng.integers(1 << 30)))
        msg = (seed, rate, round(t_rot, 2), rep["verdict"], rep["warnings"])
        if rep["verdict"] != "none":
            alarms.append(msg)
        said = [w for w in rep["warnings"] if "the curl ends at" in w]
        assert len(said) == 1, msg
        t_end, err = map(float,
                         re.search(r"ends at t = ([\d.]+) \+- ([\d.]+) s", said[0]).groups())
        assert abs(t_end - t_rot) <= max(3 * err, 0.3), msg
    assert len(alarms) <= 1, alarms


# --- bad input: one line naming the file and the row ---------------------------------

def _one_line_error(tmp_path, name, args):
    out = tmp_path / "R.json"
    res = runner.invoke(app, ["discover", str(tmp_path / name), "-o", str(out), *args])
    assert res.exit_code == 1, res.output
    lines = [ln for ln in res.output.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and name in lines[0] and "row" in lines[0], res.output
    assert "Traceback" not in res.output and not out.exists()
    return lines[0]


def test_bad_inputs_are_one_line_errors(tmp_path):
    seed = _entropy()
    rng = np.random.default_rng(seed)
    s = simulate_series(ShotModel(v0=float(rng.uniform(1.5, 2.0)), omega0=1.5),
                        noise_m=0.002, seed=seed % (1 << 30), theta_measured=False)
    write_series(tmp_path / "notheta.csv", s)
    line = _one_line_error(tmp_path, "notheta.csv", ["--baseline", "dry"])
    assert "theta" in line
    d = s.data.copy()
    d["theta"] = 0.0
    write_series(tmp_path / "three.csv", d.iloc[:3], {})
    _one_line_error(tmp_path, "three.csv", [])
    i = int(rng.integers(10, len(d) - 10))
    d.loc[i, "t"] = d.loc[i - 5, "t"]
    write_series(tmp_path / "back.csv", d, {})
    line = _one_line_error(tmp_path, "back.csv", [])
    assert f"row {i + 2}" in line, (seed, line)


def test_position_only_cli_fit_and_discover(tmp_path):
    """`simulate --position-only` at 10 Hz: the sidecar says so; fit and discover run."""
    csv = tmp_path / "P.csv"
    res = runner.invoke(app, ["simulate", "--v0", "1.8", "--omega0", "-1.5", "--fps", "10",
                              "--position-only", "--start-s", "1", "--noise-m", "0.002",
                              "--seed", str(_entropy() % (1 << 30)), "-o", str(csv)])
    assert res.exit_code == 0, res.output
    assert json.loads(csv.with_suffix(".json").read_text())["theta_measured"] is False
    res = runner.invoke(app, ["fit", str(csv), "-o", str(tmp_path / "F.json"), "-q"])
    assert res.exit_code == 0, res.output
    fit = json.loads((tmp_path / "F.json").read_text())
    assert fit["lambda_theta"] is None and fit["lambda_y"] is not None


@pytest.mark.slow
@pytest.mark.parametrize("noise_class", NOISE_CLASSES)
@pytest.mark.parametrize("effect", ["pick", "friction_patch", "late_curl", "ice_slope",
                                    "velocity_dependent_friction"])
def test_hidden_effect_named_under_each_noise_class(effect, noise_class):
    """Each vocabulary effect hidden at random place and sign under each noise class (10
    or 30 Hz, theta or not, irregular below 30 Hz), at twice the class's own 90 %
    strength (README, measured by ``scripts/bench_discover.py --noise-classes``): named
    in >= 8 of 10 cases, and no case names another effect.  Where the class's 90 %
    strength was not reached (step-like noise: effects that size are not told from
    the instrument's steps), only the second: at the largest strength measured, the
    verdict is the effect, ``none`` or ``unexplained`` - never a wrong name."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from _synth import S90_BY_CLASS, STRENGTH_CAP, class_strength, make_case

    s90 = S90_BY_CLASS[noise_class][effect]
    strength = (min(2 * s90, STRENGTH_CAP.get(effect, np.inf)) if s90 is not None
                else class_strength(effect, noise_class, 4.0))
    seed = _entropy()
    rng = np.random.default_rng(seed)
    verdicts = []
    for _ in range(10):
        inst = {"noise_class": noise_class, "rate_hz": float(rng.choice([10.0, 30.0])),
                "theta": bool(rng.random() < 0.5)}
        shots, truth = make_case(effect, strength, rng, instrument=inst,
                                 n_shots=2 if effect == "ice_slope" else 1)
        verdicts.append(discover(shots, baseline=truth["baseline"], n_boot=200,
                                 seed=int(rng.integers(1 << 30)))["verdict"])
    named = sum(v == effect for v in verdicts)
    wrong = [v for v in verdicts if v not in (effect, "none", "unexplained")]
    assert not wrong, f"seed {seed}: strength {strength:g}: {verdicts}"
    if s90 is not None:
        assert named >= 8, f"seed {seed}: strength {strength:g}: {verdicts}"


def test_persistent_instrument_noise_is_named_in_the_report():
    """Persistent instrument errors are named in REPORT.json's warnings exactly when the
    residuals' low-frequency noise (the reported ``inflation``) exceeds the limit - a
    verdict other than none may then be the instrument; white noise never warns."""
    from curltrack.discover import PERSISTENT_NOISE_WARN

    seed = _entropy()
    rng = np.random.default_rng(seed)
    for cls in ("steps", "white"):
        rep = discover(clean_case(rng, cls, float(rng.choice([10.0, 30.0])),
                                  bool(rng.random() < 0.5)),
                       n_boot=50, seed=int(rng.integers(1 << 30)), extensions=False)
        warned = any("low-frequency noise" in w for w in rep["warnings"])
        high = any(sh[c]["inflation"] > PERSISTENT_NOISE_WARN
                   for sh in rep["noise"] for c in ("x", "y", "theta")
                   if c in sh and sh[c].get("inflation") is not None)
        assert warned == high and (cls == "steps" or not warned), (
            seed, cls, rep["warnings"], rep["noise"])


def test_a_named_effect_is_not_called_the_instruments_persisting_noise():
    """A strong hidden effect (16x its 2 mm 90 % strength, white noise): the baseline's
    residuals hold far more low-frequency noise than white noise's (the effect itself),
    which the warning had called "errors of the instrument that persist" beside a verdict
    that rightly named the effect (the demo's tracked patch: ~7e4x).  Judged again on the
    named finding's residuals: the warning says the effect accounts for it, or gives
    what the finding leaves.  (A named effect whose baseline residuals stay under the
    warning's level - a late curl at 5x, seed 8131079568969598537 - gives no warning
    and is not one of the two judged.)"""
    import sys
    from pathlib import Path

    from curltrack.discover import PERSISTENT_NOISE_WARN

    sys.path.insert(0, str(Path(__file__).parent))
    from _synth import class_strength, make_case

    seed = _entropy()
    rng = np.random.default_rng(seed)
    judged = 0
    for _ in range(8):
        if judged == 2:
            break
        effect = str(rng.choice(["pick", "friction_patch", "late_curl"]))
        shots, truth = make_case(effect, class_strength(effect, "white", 16.0), rng)
        rep = discover(shots, baseline=truth["baseline"], n_boot=50,
                       seed=int(rng.integers(1 << 30)))
        if rep["verdict"] != effect:
            continue
        infl = max(sh[c]["inflation"] for sh in rep["noise"] for c in ("x", "y", "theta")
                   if c in sh and sh[c].get("inflation") is not None)
        noise = [w for w in rep["warnings"] if "low-frequency noise" in w]
        if infl <= PERSISTENT_NOISE_WARN:   # (nothing to warn of)
            assert not noise, (seed, effect, infl, noise)
            continue
        judged += 1
        # (judged again: accounted for, or what the finding leaves beside it)
        assert noise and all("the named effect accounts for what persisted" in w
                             or f"with {effect} fitted, still" in w for w in noise), (
            seed, effect, rep["warnings"])
    assert judged == 2, f"seed {seed}: named with a warning's residuals in {judged} of 8"


def test_a_peer_simulators_physics_is_not_called_none(tmp_path):
    """A shot drawn by physics of another simulator's (a friction law that is not a
    power law, a curl that grows as the rock slows, another spin decay: ``_world``),
    2 mm white noise: the paper's model misses it by several times the noise, smoothly.
    Read as an instrument's persisting errors, that gave ``none`` on 6 of 6 draws; a
    smooth misfit is the model's (:func:`curltrack.discover.residuals.smooth_misfit`)
    and the verdict must not say the model describes the shot."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from _world import make_peer_physics_world

    seed = _entropy()
    shot, truth = make_peer_physics_world(np.random.default_rng(seed))
    f, out = tmp_path / "peer.csv", tmp_path / "report.json"
    write_series(f, shot)
    res = runner.invoke(app, ["discover", str(f), "-o", str(out), "--seed", "1"])
    assert res.exit_code == 0, (seed, res.output)
    rep = json.loads(out.read_text())
    assert rep["verdict"] != "none", (seed, truth)
    if rep["verdict"] == "unexplained":
        assert (rep["unexplained"].get("smooth_misfit")
                or rep["structure_before"]["structured"]), (seed, rep["unexplained"])
        # and the command line says why, in one line
        why = [ln for ln in res.output.splitlines() if ln.startswith("why: ")]
        assert len(why) == 1 and len(why[0]) > 20, (seed, res.output)


def test_an_effect_that_leaves_the_peers_misfit_is_not_named(tmp_path):
    """A regression draw of the peer world (found in 40 fresh draws, with a late curl in
    another): the baseline misses theta 6.5 times its rows' scatter, smoothly; a "pick"
    of 0.02 m/s at the stop took the largest part of it (delta-BIC 6221 over a threshold
    of 1300) and was named, while theta was still missed 3.7 times its scatter.  A named
    effect must take the model's smooth misfit away: the verdict is ``unexplained``,
    after the pick, with the misfit it leaves."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from _world import make_peer_physics_world

    shot, _ = make_peer_physics_world(np.random.default_rng(7453703524685583807))
    f, out = tmp_path / "peer.csv", tmp_path / "report.json"
    write_series(f, shot)
    res = runner.invoke(app, ["discover", str(f), "-o", str(out), "--seed", "1"])
    assert res.exit_code == 0, res.output
    rep = json.loads(out.read_text())
    assert rep["verdict"] == "unexplained", rep["verdict"]
    left = rep["unexplained"]["smooth_misfit"]
    assert rep["unexplained"]["after_model"] == "pick"
    assert any(m["coord"] == "theta" and m["ratio"] > 3 for m in left), left
    assert "not the shot" in res.output


def test_clean_shots_show_no_smooth_misfit():
    """The smooth-misfit rule never fires on clean shots of any noise class (white,
    AR(1), steps, heavy tails, vibration, values rounded to a centimetre), 10 or 30 Hz,
    with or without theta, single or in sessions: their residuals are the rows' scatter,
    or jump (steps).  (Measured: 0 of 60 per class, 0 of 40 vibration and quantised once
    the noise of rounded values was floored at step / sqrt 12, 0 of 12 sessions.)"""
    from curltrack.discover.model import JointModel
    from curltrack.discover.residuals import smooth_misfit
    from curltrack.discover.shots import shot_from_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    for i in range(12):
        cls = str(rng.choice(ALL_NOISE_CLASSES))
        n = int(rng.choice([1, 1, 3]))
        series = clean_case(rng, cls, float(rng.choice([10.0, 30.0])), bool(rng.random() < 0.5),
                            n_shots=n)
        base = JointModel([shot_from_series(s) for s in series], "paper")
        found = smooth_misfit(base, base.fit(max_nfev=120))
        assert not found, (seed, i, cls, n, found)


def test_a_series_measured_per_field_is_read_as_its_exposures(tmp_path):
    """Interlaced video is tracked per field: two rows per frame, a ``field`` column
    (contract).  Its exposures are consecutive as 2 frame + field: by ``frame`` alone
    no two rows were, and ``discover`` refused every tracked interlaced video ("too few
    consecutive measured frames", session 38: 34 of 34 camcorder clips).  A clean
    59.94 Hz field series: its noise read as drawn, verdict ``none``; a field that is
    not 0 or 1 is a one-line error naming the row."""
    from curltrack.instrument import Sampling
    from curltrack.series import read_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    noise_class = str(rng.choice(["white", "ar1"]))
    sm, sr = TYPICAL_SCALE[noise_class]
    model = ShotModel(v0=rng.uniform(1.4, 2.2), omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 3))
    sim = simulate_series(model, noise_m=sm, noise_rad=sr, noise_class=noise_class,
                          seed=int(rng.integers(1 << 30)),
                          sampling=Sampling(rate_hz=59.94)).data
    d = sim.assign(frame=np.arange(len(sim)) // 2, field=np.arange(len(sim)) % 2)
    path = tmp_path / "fields.csv"
    d.to_csv(path, index=False)
    series = read_series(path)
    assert (series.data["field"] == d["field"]).all()
    rep = discover(series, n_boot=200, seed=int(rng.integers(1 << 30)))
    assert rep["verdict"] == "none", f"seed {seed} ({noise_class}): {rep['verdict']}"
    noise = rep.summary()["noise"][0]
    # What consecutive exposures pin is the noise's innovation, sigma sqrt(1 - rho^2):
    # the AR(1) class's correlation time is 0.05 s, rho 0.72 per 59.94 Hz field.  (Its
    # sigma and rho apart are loose there: a draw read rho 0.89 and sigma 1.58 x,
    # seed 5120471726407062914; 99 % of pure-noise draws within 0.80-2.6 x.)  Read by
    # frame alone, or fields out of order, the innovation would be far off.
    rho = np.exp(-1.0 / 59.94 / 0.05) if noise_class == "ar1" else 0.0
    for c in ("x", "y"):
        ratio = noise[c]["sigma_innovation"] / (sm * np.sqrt(1 - rho ** 2))
        assert 0.8 < ratio < 1.25, f"seed {seed}: {c} {noise[c]} ({ratio:.2f})"
    bad = d.copy()
    bad.loc[7, "field"] = 2
    bad.to_csv(path, index=False)
    res = runner.invoke(app, ["discover", str(path), "-o", str(tmp_path / "r.json")])
    assert res.exit_code == 1 and "row 9" in res.output and "'field'" in res.output, res.output


def test_an_instrument_whose_errors_persist_is_held_to_its_stated_sigma():
    """A tracker's errors have a slow part besides their row-to-row scatter (measured on
    67 clips through real cameras: 0.5-4x the white part).  Where the series says so
    (``noise_persists``, as the tracker's sidecar does) and states its rows' sigma, a
    baseline misfit within that sigma is the instrument's, not 'a misfit no noise model
    of the rows explains'; the same residuals without the flag are (the rule that named
    3 of 40 clean tracked-class shots 'unexplained').  A tracked video's sidecar without
    the key counts as saying it."""
    from dataclasses import replace

    from curltrack.discover.model import JointModel
    from curltrack.discover.residuals import smooth_misfit
    from curltrack.discover.shots import shot_from_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    fired = []
    for _ in range(150):
        s = clean_case(rng, "tracked", 30.0, True)[0]
        assert s.meta["noise_persists"], seed
        bare = replace(s, meta={k: v for k, v in s.meta.items() if k != "noise_persists"})
        model = JointModel([shot_from_series(bare)], "paper")
        fit = model.fit(max_nfev=120)
        if not smooth_misfit(model, fit):
            continue
        fired.append(s)
        held = JointModel([shot_from_series(s)], "paper")
        assert held.shots[0].noise_persists, seed
        assert not smooth_misfit(held, fit), seed    # the same fit, held to its sigma
        video = JointModel([shot_from_series(bare.with_meta(video="shot.mp4"))], "paper")
        assert video.shots[0].noise_persists and not smooth_misfit(video, fit), seed
        if len(fired) == 2:
            break
    # (a slow part >= ~1.7x the white one makes the residuals' RMS twice the rows'
    # scatter: r is log-uniform in 0.5-4, so 44 % of draws have it, but a short slow
    # time leaves less: the bare rule fires on ~12 % of draws (7 of 60), so 30 draws
    # missed it in ~2 % of runs - seed 149948610540393776; 150 draws without one
    # firing, ~1e-8 by chance, is a broken generator)
    assert fired, seed


def test_persistent_noise_warning_after_a_finding_that_leaves_it():
    """A named finding that leaves a coordinate's low-frequency noise above the warning
    level: the warning gives both levels (it recursed without end until session 39 -
    a RecursionError out of ``discover`` on a tracked-class shot with a hidden
    velocity-dependent friction)."""
    from curltrack.discover import PERSISTENT_NOISE_WARN, persistent_noise_warnings

    seed = _entropy()
    rng = np.random.default_rng(seed)
    before = float(rng.uniform(2, 50) * PERSISTENT_NOISE_WARN)
    left = float(rng.uniform(1.1, 0.9 * before / PERSISTENT_NOISE_WARN) * PERSISTENT_NOISE_WARN)
    gone = float(rng.uniform(0.1, 0.9) * PERSISTENT_NOISE_WARN)
    out = persistent_noise_warnings([("a.csv", "x", before), ("a.csv", "y", before),
                                     ("a.csv", "theta", 0.5 * PERSISTENT_NOISE_WARN)],
                                    after={("a.csv", "x"): left, ("a.csv", "y"): gone},
                                    named="pick")
    assert len(out) == 2, (seed, out)
    assert f"still {left:.0f}x" in out[0] and f"{before:.0f}x" in out[0], (seed, out[0])
    assert "accounts for what persisted" in out[1], (seed, out[1])
