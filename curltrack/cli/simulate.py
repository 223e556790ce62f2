"""``curltrack simulate``: forward model of a shot -> SIM.csv (+ sidecar)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..physics.effects import EFFECTS
from ..rig import BAND_RADIUS_M, INERTIA_RADIUS_M
from ._app import app, check_outputs, fail, guarded

_HELP = f"""Simulate a shot and write it as a SHOT.csv-format series (and sidecar SIM.json).

Frame: origin at the start, +y along the initial velocity, theta counter-clockwise seen
from above.  omega0 > 0 is a counter-clockwise spin, which curls to -x.

Defaults (paper model) are the paper's pebbled-ice draw: phi_y = -0.19,
alpha_y = 0.0076 (m/s)^0.19, phi_theta = -1.198 (its lambda_theta = 1.455), alpha_theta
tied so that rotation stops when translation does, a_T = 5e-3 m/s^2, R = {INERTIA_RADIUS_M} m,
r = {BAND_RADIUS_M} m (or the rig's).  `--v0 2.0 --omega0 1.5` gives a ~26 s draw with ~0.9 m
of curl.  --phi/--alpha set both channels; --phi-y ... override per channel.

Effects: --effect NAME followed by its --param KEY=VALUE (names: {', '.join(EFFECTS)}).
Example:
--effect ice_slope --param slope_x_mm_per_m=1.5 --effect pick --param t_s=8
--param domega_rad_per_s=-0.5

Other instruments: --noise-class white|ar1|steps|heavy (how the errors behave; --noise-m
and --noise-rad set their scale), --fps 10 --jitter-s 0.003 --gaps 2 --start-s 1.0
(irregular sampling, first row 1 s after release), --position-only (theta not measured).
A session: --shots 5 writes SIM_1.csv ... SIM_5.csv, shots of both spins with v0 and
|omega0| within +-15 % / +-50 % of the given ones and alpha spread by --alpha-spread
(relative 1 sigma, default 0.05) around one sheet's friction.
"""


def _usage(message: str, param_hint: str = "") -> None:
    """A usage error: one line, exit status 2."""
    fail(f"{param_hint}: {message}" if param_hint else message, code=2)


def _parse_effects(names: List[str], params: List[str]):
    """Pair each --param with an effect.

    Click does not keep the interleaving of --effect and --param, but parameter names are
    unique across effect types; for repeated effects (two picks) a key goes to the latest
    occurrence that already has parameters and lacks this one, else to the first that
    lacks it — right whenever each effect's --param's follow it.
    """
    from ..physics.effects import Effect

    for name in names:
        if name not in EFFECTS:
            _usage(f"unknown effect {name!r}; expected one of {', '.join(sorted(EFFECTS))}",
                   param_hint="--effect")
    chosen = [(name, {}) for name in names]
    for item in params:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            _usage(f"expected KEY=VALUE, got {item!r}", param_hint="--param")
        try:
            value = float(text)
        except ValueError:
            _usage(f"{key}: expected a number, got {text!r}", param_hint="--param")
        lacking = [p for n, p in chosen if key in EFFECTS[n].param_names and key not in p]
        started = [p for p in lacking if p]
        owner = started[-1] if started else (lacking[0] if lacking else None)
        if owner is None:
            valid = sorted({k for n in names for k in EFFECTS[n].param_names})
            _usage(
                f"{key!r} is not a parameter of the given effect(s) {names or '(none)'} "
                f"(or is given twice); expected some of {valid}", param_hint="--param")
        owner[key] = value
    return tuple(Effect(n, p) for n, p in chosen)


@app.command(help=_HELP)
@guarded
def simulate(
    v0: float = typer.Option(..., "--v0", help="Initial speed (m/s) along +y."),
    omega0: float = typer.Option(..., "--omega0", help="Initial spin (rad/s), > 0 CCW."),
    output: Path = typer.Option(..., "-o", "--output", help="SIM.csv or SIM.parquet."),
    phi: Optional[float] = typer.Option(None, "--phi", help="phi of mu = alpha u^phi (both)."),
    alpha: Optional[float] = typer.Option(None, "--alpha", help="alpha, (m/s)^-phi (both)."),
    a_T: Optional[float] = typer.Option(None, "--a-T", "--a-t",
                                        help="Size of the transverse acceleration (m/s^2)."),
    phi_y: Optional[float] = typer.Option(None, "--phi-y", help="phi, translation."),
    alpha_y: Optional[float] = typer.Option(None, "--alpha-y", help="alpha, translation."),
    phi_theta: Optional[float] = typer.Option(None, "--phi-theta", help="phi, rotation."),
    alpha_theta: Optional[float] = typer.Option(None, "--alpha-theta", help="alpha, rotation."),
    effect: List[str] = typer.Option([], "--effect", help="Effect name (repeatable)."),
    param: List[str] = typer.Option([], "--param", help="KEY=VALUE of the effect before."),
    noise_m: float = typer.Option(0.0, "--noise-m", help="Position noise, 1 sigma (m)."),
    noise_rad: float = typer.Option(0.0, "--noise-rad", help="Angle noise, 1 sigma (rad)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Noise seed."),
    rig: Optional[Path] = typer.Option(None, "--rig", help="Rig TOML (R, r, fps)."),
    fps: Optional[float] = typer.Option(None, "--fps", help="Frame rate (default: rig or 30)."),
    tail_s: float = typer.Option(1.0, "--tail-s", help="Rest recorded after the stop (s)."),
    noise_class: str = typer.Option("white", "--noise-class",
                                    help="white | ar1 | steps | heavy | tracked | "
                                         "vibration | quantised."),
    jitter_s: float = typer.Option(0.0, "--jitter-s", help="Timestamp jitter, 1 sigma (s)."),
    gaps: int = typer.Option(0, "--gaps", help="Number of gaps with no rows."),
    max_gap_s: float = typer.Option(2.0, "--max-gap-s", help="Longest gap (s)."),
    start_s: float = typer.Option(0.0, "--start-s", help="First row after release (s)."),
    position_only: bool = typer.Option(False, "--position-only",
                                       help="Theta not measured (empty column)."),
    shots: int = typer.Option(1, "--shots", help="Shots of one session (SIM_1.csv ...)."),
    alpha_spread: float = typer.Option(0.05, "--alpha-spread",
                                       help="Session: relative 1 sigma spread of alpha."),
    model: str = typer.Option("paper", "--model", help="paper | segment."),
    friction_direction: str = typer.Option(
        "film", "--friction-direction", help="segment model: ice | film."),
    film_drag: Optional[float] = typer.Option(
        None, "--film-drag", help="segment model: film speed / segment speed (kappa)."),
    asymmetry: Optional[float] = typer.Option(
        None, "--asymmetry", help="segment model: front-back friction asymmetry (epsilon)."),
):
    from ..errors import ParameterError
    from ..rig import default_rig, load_rig
    from ..series import sidecar_path, write_series
    from ..instrument import ALL_NOISE_CLASSES, Sampling, session_models
    from ..simulate import simulate_series

    outputs = [output] if shots == 1 else \
        [output.with_name(f"{output.stem}_{i + 1}{output.suffix}") for i in range(shots)]
    check_outputs([rig], [pair for o in outputs
                          for pair in (("-o", o), ("-o (its sidecar)", sidecar_path(o)))])
    if shots < 1:
        _usage(f"expected >= 1, got {shots}", param_hint="--shots")
    if shots > 1 and model != "paper":
        _usage("sessions use the paper model", param_hint="--shots")
    if noise_class not in ALL_NOISE_CLASSES:
        _usage(f"expected one of {', '.join(ALL_NOISE_CLASSES)}, got {noise_class!r}",
               param_hint="--noise-class")
    if model not in ("paper", "segment"):
        _usage(f"expected paper or segment, got {model!r}", param_hint="--model")
    if friction_direction not in ("ice", "film"):
        _usage(f"expected ice or film, got {friction_direction!r}",
               param_hint="--friction-direction")
    effects = _parse_effects(effect, param)
    the_rig = load_rig(rig) if rig else default_rig()
    if fps is None:
        fps = the_rig.fps or 30.0
    if a_T is not None and a_T < 0:
        raise ParameterError(f"must be >= 0 (got {a_T}); it is a size, the spin sets its "
                             f"side", where="--a-T")
    if model == "paper":
        from ..physics import ShotModel

        kw = {k: v for k, v in dict(
            phi_y=phi_y if phi_y is not None else phi,
            alpha_y=alpha_y if alpha_y is not None else alpha,
            phi_theta=phi_theta if phi_theta is not None else phi,
            alpha_theta=alpha_theta if alpha_theta is not None else alpha,
            a_T=a_T).items() if v is not None}
        shot = ShotModel.from_rig(the_rig, v0=v0, omega0=omega0, **kw)
    else:
        from ..physics.segment import SegmentModel

        for name, value in (("--phi-y", phi_y), ("--alpha-y", alpha_y), ("--a-T", a_T),
                            ("--phi-theta", phi_theta), ("--alpha-theta", alpha_theta)):
            if value is not None:
                _usage("the segment model has one friction law "
                                         "(--phi, --alpha) and no a_T", param_hint=name)
        kw = {k: v for k, v in dict(phi=phi, alpha=alpha, film_drag=film_drag,
                                    asymmetry=asymmetry).items() if v is not None}
        shot = SegmentModel.from_rig(the_rig, v0=v0, omega0=omega0,
                                     friction_direction=friction_direction, **kw)
    sampling = Sampling(rate_hz=fps, jitter_s=jitter_s, start_s=start_s, n_gaps=gaps,
                        max_gap_s=max_gap_s)
    import numpy as np

    rng = np.random.default_rng(seed)
    models = [shot] if shots == 1 else session_models(
        shot, shots, rng, alpha_spread=alpha_spread,
        v0_range=(0.85 * v0, 1.15 * v0), omega0_range=(0.5 * abs(omega0), 1.5 * abs(omega0)))
    seeds = [seed] if shots == 1 else [int(s) for s in rng.integers(0, 2**31, shots)]
    for out, one, sd in zip(outputs, models, seeds):
        series = simulate_series(one, effects, fps=fps, noise_m=noise_m, noise_rad=noise_rad,
                                 seed=sd, tail_s=tail_s, noise_class=noise_class,
                                 sampling=sampling, theta_measured=not position_only)
        side = write_series(out, series)
        m = series.meta
        typer.echo(f"wrote {out} ({len(series.data)} rows at {fps:g} Hz; stops: translation "
                   f"{m['t_stop_translation']:.3f} s, rotation {m['t_stop_rotation']:.3f} s) "
                   f"and {side}")
