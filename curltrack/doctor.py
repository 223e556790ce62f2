"""Check a video + rig before a long run: is there anything to measure?

``diagnose(video, rig)`` reads a few frames spread over the video (never the whole of
it) and runs the first steps of the pipeline on each: the container (codec, frame rate,
frame count), the rig's markers, the thread grid (spacing, residual), the rock's size in
the image and the camera height implied by the parallax between the marker plane and
the ice, and how fast the camera turns between consecutive frames.  The result is a
checklist; a check is *fatal* when ``track`` cannot succeed
(no frames, no markers, no grid anywhere), a *warning* when it will run but the result
may suffer (markers missing in some frames, grid only partly visible, a tiny rock, an
implausible camera height, a low frame rate).

Example::

    report = diagnose("shot.mp4", load_rig("rig.toml"))
    print(report.format())          # ✓ / ✗ / ! lines with advice
    report.ok                       # False when something is fatal
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from .errors import CurltrackError
from .rig import Rig

__all__ = ["Check", "DoctorReport", "diagnose"]

#: Frames sampled over the video.
N_SAMPLES = 6
#: Below this frame rate stop times and λ lose precision (frames/s).
MIN_FPS = 20.0
#: Rock diameter in the image below which markers are a few px only (px).
MIN_ROCK_PX = 45.0
#: Thread spacing in the image below which threads blur together (px).
MIN_SPACING_PX = 8.0
#: Camera heights a rig of this kind is mounted at (m).
HEIGHT_RANGE_M = (0.8, 8.0)
# Camera turn between consecutive frames (deg/frame): above the rig's
# tracking.turn_warn_deg_per_frame positions lose accuracy (the limit ``track`` warns
# at); above turn_fail_deg_per_frame the grid's cell index is lost (~10 deg/frame).
#: Sampled frames that are also checked against their next frame (camera turn rate).
N_PAIRS = 3


@dataclass
class Check:
    """One line of the checklist.

    Attributes
    ----------
    name : str
        ``video``, ``fps``, ``length``, ``decode``, ``markers``, ``grid``, ``rock_size``,
        ``camera_height``, ``grid_scale``, ``camera_turn``, ``release`` (the video
        begins before the release: the rock speeds up over its first frames).
    status : str
        ``"ok"``, ``"warn"`` or ``"fail"`` (fatal: ``track`` cannot succeed).
    detail : str
        What was measured, with units.
    advice : str
        What to do about it (empty when ok).
    values : dict
        The numbers behind ``detail`` (JSON-ready).
    """

    name: str
    status: str
    detail: str
    advice: str = ""
    values: dict = field(default_factory=dict)


@dataclass
class DoctorReport:
    """The checklist for one video + rig."""

    video: str
    rig: str | None
    checks: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """False when any check is fatal."""
        return not any(c.status == "fail" for c in self.checks)

    def check(self, name: str) -> Check | None:
        return next((c for c in self.checks if c.name == name), None)

    def to_dict(self) -> dict:
        return {"video": self.video, "rig": self.rig, "ok": self.ok,
                "checks": [asdict(c) for c in self.checks]}

    def format(self) -> str:
        """The checklist as text: one line per check (✓ ok, ! warning, ✗ fatal)."""
        mark = {"ok": "✓", "warn": "!", "fail": "✗"}
        lines = [f"curltrack doctor: {self.video}"]
        for c in self.checks:
            lines.append(f"  {mark[c.status]} {c.name:<14s} {c.detail}")
            if c.advice:
                lines.append(f"    {'':<14s} -> {c.advice}")
        lines.append("  verdict: " + ("ready to track" if self.ok else
                                      "track will fail: fix the ✗ items first"))
        return "\n".join(lines)


def _sample(verdict, image, rig, det):
    """What doctor reports of one frame, from ``track``'s verdict on it (dict)."""
    from .track.parallax import mirrored_layout, similarity_fit

    out = {"markers_found": list(verdict.markers_found), "grid": None,
           "grid_msg": verdict.grid_status, "status": verdict.status, "scale": np.nan,
           "outline_scale": np.nan, "rock_px": np.nan, "spacing_px": np.nan,
           "residual_px": np.nan}
    L = det.layout_m
    xy = verdict.markers_px
    if xy is not None:
        sep_m = float(np.hypot(*(L[0] - L[1])))
        out["rock_px"] = rig.rock_diameter_m * float(np.hypot(*(xy[0] - xy[1]))) / sep_m
    # The camera's turn between frames: from a calibration of each frame alone (lens
    # and lattice fitted on the frame itself: the most precise angle, and measured also
    # where track could not follow the grid - a turn too fast for it)
    out["yaw_deg"] = _yaw_alone(image, rig, det, xy)
    cal = verdict.calibration
    if cal is None:
        return out
    out["grid"] = True
    out["spacing_px"], out["residual_px"] = float(cal.spacing_px), float(cal.residual_px)
    out["n_threads"] = list(cal.n_threads)
    out["lens"] = (float(cal.dist[0]), float(cal.dist[1]), cal.lens_radius_px,
                   float(cal.K[0, 0]))   # (k1, k2 at this reference focal length, px)
    if out["yaw_deg"] is None:
        out["yaw_deg"] = cal.yaw_deg()  # image +u in the lattice
    if xy is not None:
        ice = cal.image_to_ice(xy)
        if np.isfinite(ice).all():
            from .track.outline import outline_radius

            c, _, out["scale"], _ = similarity_fit(L, ice)
            out["mirrored"] = mirrored_layout(L, ice)
            R = rig.rock_diameter_m / 2
            out["outline_scale"] = outline_radius(image, cal.H, cal.K, cal.dist, c, R)[0] / R
    return out


def _yaw_alone(image, rig, det, markers_px):
    """The lattice's angle in the image (deg) from a calibration of ``image`` alone (the
    rock masked when its markers were found), or None."""
    import cv2

    from .track.pipeline import _calibrate, blank_frame, rock_disc

    if image is None or blank_frame(image, rig.tracking):
        return None
    mask = None
    if markers_px is not None:
        mask = np.zeros(image.shape[:2], np.uint8)
        (x, y), rad = rock_disc(det.layout_m, markers_px, rig.rock_diameter_m)
        cv2.circle(mask, (x, y), rad, 255, -1)
    cal, _ = _calibrate(image, rig, mask)
    return None if cal is None else cal.yaw_deg()


def diagnose(video, rig: Rig, n_samples: int = N_SAMPLES, frames=None,
             progress: bool | None = False) -> DoctorReport:
    """Check a video and a rig before tracking.

    Parameters
    ----------
    video : path
        The shot video.
    rig : Rig
        The rig (grid spacings and colours, rock, markers, camera).
    n_samples : int
        Frames to examine, spread evenly from the first to the last.
    frames : iterable of int, optional
        Examine these frames instead.
    progress : bool or None
        A progress bar on stderr while track's loop runs up to the last frame examined
        (None: when stderr is a terminal).

    Each frame is judged by ``track``'s own per-frame loop, run from the video's start
    (:func:`curltrack.track.check.check_frames`: the same steps, thresholds and
    messages), so a frame doctor calls lost is ``ok`` = 0 in ``track``'s output and the
    reverse (``frames`` check).

    Returns
    -------
    DoctorReport
        ``report.ok`` is False when ``track`` cannot succeed.  Raises nothing for a bad
        video: an unreadable file is a failed ``video`` check.
    """
    from .progress import progress_bar
    from .track.check import check_frames, frame_reader
    from .track.markers import MarkerDetector
    from .video import probe_video

    rep = DoctorReport(str(video), rig.source)
    try:
        info = probe_video(video, fps_override=rig.fps)
    except CurltrackError as exc:
        if getattr(exc, "where", None) == "[camera].fps":
            rep.checks.append(Check("fps", "fail", exc.message,
                                    "remove [camera].fps from the rig or check the video"))
            return rep
        rep.checks.append(Check("video", "fail", str(exc),
                                "re-export the video (H.264 mp4) or check the file"))
        return rep
    rep.checks.append(Check(
        "video", "ok", f"{info.describe()}; {info.n_frames} frames, {info.duration_s:.2f} s",
        values=asdict(info)))
    fps_src = "container" + (", the rig's fps agrees" if rig.fps else "")
    if info.fps < MIN_FPS:
        rep.checks.append(Check("fps", "warn", f"{info.fps:.3g} frames/s ({fps_src})",
                                f"below {MIN_FPS:g} fps stop times and lambda lose "
                                "precision; record at 30 fps or more",
                                values={"fps": info.fps}))
    else:
        rep.checks.append(Check("fps", "ok", f"{info.fps:.4g} frames/s ({fps_src})",
                                values={"fps": info.fps}))
    if info.n_frames < 12:
        rep.checks.append(Check("length", "fail", f"only {info.n_frames} frames",
                                "a shot needs at least 12 measured frames; record the "
                                "whole shot until the rock rests"))
    if frames is None:
        idx = np.unique(np.linspace(0, info.n_frames - 1, max(1, min(n_samples, info.n_frames)))
                        .round().astype(int))
    else:
        idx = np.unique(np.asarray(list(frames), int))
        bad = idx[(idx < 0) | (idx >= info.n_frames)]
        if bad.size:
            from .errors import ParameterError

            raise ParameterError(f"frame {int(bad[0])} is outside the video (frames "
                                 f"0-{info.n_frames - 1})", path=video, where="frames")
    nxt = [int(i) + 1 for i in idx[:N_PAIRS] if i + 1 < info.n_frames]
    det = MarkerDetector(rig)
    read = frame_reader(video, info.n_frames, rig.fps)
    found = {}
    try:
        judged = sorted(set(idx.tolist()) | set(nxt))
        problems: list = []
        with progress_bar("doctor: track's loop", judged[-1] + 1 if judged else 0,
                          enabled=progress) as advance:
            verdicts = check_frames(video, judged, rig, fps_override=rig.fps,
                                    progress=advance, problems=problems)
        for verdict in verdicts:
            found[verdict.frame] = _sample(verdict, read(verdict.frame), rig, det)
    except CurltrackError as exc:
        rep.checks.append(Check("decode", "fail", str(exc), "the file is damaged; re-export"))
        return rep
    samples = [(int(i), found[int(i)]) for i in idx if int(i) in found]
    _frame_check(rep, samples)
    _marker_checks(rep, rig, samples)
    _grid_checks(rep, rig, samples)
    _geometry_checks(rep, rig, samples)
    _turn_check(rep, [(found[i - 1], found[i], i - 1) for i in nxt
                      if i - 1 in found and i in found], info.fps, rig.tracking)
    for exc in problems:   # (the rock's speed over the frames run: track's own rule)
        rep.checks.append(Check("release", "fail", exc.message,
                                "give --start-frame at the release frame named here"))
    return rep


def _turn_check(rep, pairs, fps: float, settings):
    """Camera turn between consecutive frames, from the lattice's angle in each."""
    from .calib.grid import lattice_turn_deg

    rates = []
    for a, b, frame in pairs:
        if a.get("yaw_deg") is None or b.get("yaw_deg") is None:
            continue
        rates.append((abs(float(lattice_turn_deg(a["yaw_deg"], b["yaw_deg"]))), frame))
    if not rates:
        return
    worst, frame = max(rates)
    per_s = worst * fps
    values = {"max_turn_deg_per_frame": worst, "max_turn_deg_per_s": per_s, "at_frame": frame,
              "pairs": len(rates)}
    detail = (f"up to {worst:.2f} deg/frame ({per_s:.0f} deg/s) over {len(rates)} "
              f"frame pair(s)")
    warn, fail = settings.turn_warn_deg_per_frame, settings.turn_fail_deg_per_frame
    if worst > fail:
        rep.checks.append(Check("camera_turn", "fail", detail + f" at frame {frame}",
                                "the camera turns too fast to follow the grid: hold it "
                                "steadier or mount it", values))
    elif worst > warn:
        rep.checks.append(Check("camera_turn", "warn", detail + f" at frame {frame}",
                                f"above {warn:g} deg/frame positions lose accuracy "
                                "(several mm): turn the camera more slowly", values))
    else:
        rep.checks.append(Check("camera_turn", "ok", detail, values=values))


def _frame_check(rep, samples):
    """Each sampled frame's verdict, as ``track`` will give it (ok / why not)."""
    lost = [(f, s["status"]) for f, s in samples if s["status"]]
    values = {"verdicts": {str(f): s["status"] for f, s in samples},
              "grid": {str(f): s["grid_msg"] for f, s in samples}}
    detail = (f"{len(samples) - len(lost)}/{len(samples)} sampled frames measurable as "
              "track measures them")
    if lost:
        reasons: dict = {}   # (frames with one reason together)
        for f, why in lost:
            reasons.setdefault(why, []).append(f)
        rep.checks.append(Check("frames", "warn", detail + "; " + "; ".join(
            f"frame{'s' if len(fs) > 1 else ''} {_frames_text(fs)}: {why}"
            for why, fs in reasons.items()), "track will give these frames ok = 0 "
            "(see the checks below for the causes)", values))
    else:
        rep.checks.append(Check("frames", "ok", detail, values=values))


def _frames_text(frames) -> str:
    return ", ".join(str(f) for f in frames) if frames else "none"


def _marker_checks(rep, rig, samples):
    n = len(samples)
    per = np.array([s["markers_found"] for _, s in samples], bool).reshape(n, -1)
    counts = {m.color: int(per[:, i].sum()) for i, m in enumerate(rig.markers)}
    all_found = [f for (f, _), row in zip(samples, per) if row.all()]
    detail = (f"all markers in {len(all_found)}/{n} sampled frames; per colour: "
              + ", ".join(f"{c} {k}/{n}" for c, k in counts.items()))
    values = {"frames_sampled": [f for f, _ in samples], "frames_all_found": all_found,
              "per_colour": counts}
    if not all_found:
        missing = [c for c, k in counts.items() if k == 0] or list(counts)
        from .track.markers import NO_COLOUR

        advice = (NO_COLOUR if any(NO_COLOUR in s["status"] for _, s in samples) else
                  "check the [[markers]] colours in the rig against the video, and that "
                  "the rock is in view")
        rep.checks.append(Check("markers", "fail", detail,
                                f"no marker of colour {', '.join(missing)} seen: {advice}",
                                values))
    elif len(all_found) < n:
        lost = [f for f, _ in samples if f not in all_found]
        rep.checks.append(Check("markers", "warn", detail,
                                f"markers not all visible in frame(s) {_frames_text(lost)} "
                                "(occluded, out of view, or blurred): those frames will "
                                "be ok = 0", values))
    else:
        rep.checks.append(Check("markers", "ok", detail, values=values))


def _grid_checks(rep, rig, samples):
    n = len(samples)
    found = [(f, s) for f, s in samples if s["grid"]]
    values = {"frames_with_grid": [f for f, _ in found]}
    if not found:
        msg = next((s["grid_msg"] for _, s in samples if s["grid_msg"]), "")
        # without markers the rock cannot be masked out, and its edge can hide the
        # threads' periodicity: then the grid verdict is not reliable, only a warning
        unmasked = not any(all(s["markers_found"]) for _, s in samples)
        rep.checks.append(Check("grid", "warn" if unmasked else "fail",
                                f"no thread grid in any of {n} sampled frames ({msg})"
                                + (" — rock not masked (no markers), unreliable"
                                   if unmasked else ""),
                                f"check [grid] spacing_x_m/spacing_y_m "
                                f"({rig.spacing_x_m:g}/{rig.spacing_y_m:g} m) and colours "
                                "against the ice, the focus and the lighting", values))
        return
    sp = float(np.median([s["spacing_px"] for _, s in found]))
    res = float(np.median([s["residual_px"] for _, s in found]))
    values.update(spacing_px=sp, residual_px=res)
    detail = (f"found in {len(found)}/{n} sampled frames; spacing {sp:.1f} px, residual "
              f"{res:.2f} px")
    cut = [s["lens"] for _, s in found if s["lens"][2] is not None]
    if cut:  # a strong wide-angle lens, confirmed by the threads only near the centre
        k1, k2, r, f = cut[0][0], cut[0][1], min(c[2] for c in cut), cut[0][3]
        values["lens_radius_px"] = r
        detail += (f"; wide-angle lens (k1 {k1:.3f}, k2 {k2:.3f} at the reference focal "
                   f"length {f:.0f} px) confirmed by the threads "
                   f"within {r:.0f} px of the image centre: the rock is not measured beyond")
    if len(found) < n:
        lost = [f for f, s in samples if not s["grid"]]
        rep.checks.append(Check("grid", "warn", detail,
                                f"grid not found in frame(s) {_frames_text(lost)}: those "
                                "frames will be lost", values))
    elif sp < MIN_SPACING_PX:
        rep.checks.append(Check("grid", "warn", detail,
                                f"threads only {sp:.1f} px apart: move the camera lower or "
                                "use a longer lens", values))
    else:
        rep.checks.append(Check("grid", "ok", detail, values=values))


def _geometry_checks(rep, rig, samples):
    rock = [s["rock_px"] for _, s in samples if np.isfinite(s["rock_px"])]
    if rock:
        d = float(np.median(rock))
        ok = d >= MIN_ROCK_PX
        rep.checks.append(Check(
            "rock_size", "ok" if ok else "warn",
            f"rock {d:.0f} px across ({rig.rock_diameter_m:g} m in the rig)",
            "" if ok else f"the rock is under {MIN_ROCK_PX:.0f} px: markers are a few px; "
            "move the camera lower or use a higher resolution", {"rock_px": d}))
    scales = np.array([s["scale"] for _, s in samples], float)
    scales = scales[np.isfinite(scales)]
    if scales.size == 0:
        rep.checks.append(Check("camera_height", "warn", "not measurable (needs markers and "
                                "grid in the same frame)",
                                "give [camera].height_m in the rig", {}))
        return
    from .track.outline import scale_check
    from .track.parallax import ICE_REFRACTIVE_INDEX, layout_scale_mismatch

    s = float(np.median(scales))
    depth = rig.grid_depth_m / ICE_REFRACTIVE_INDEX
    mirrored = float(np.mean([x.get("mirrored", False) for _, x in samples
                              if np.isfinite(x["scale"])]))
    mismatch = layout_scale_mismatch(s, rig, mirrored) or scale_check(
        [x["scale"] for _, x in samples], [x["outline_scale"] for _, x in samples], rig,
        rig.rock_height_m + depth, depth)
    if mismatch:  # (track stops with this error)
        rep.checks.append(Check("camera_height", "fail", mismatch,
                                "the grid's scale and the rock disagree: track would stop "
                                "(see the line above for what to check)",
                                {"layout_scale": s}))
        return
    _scale_resolution_check(rep, rig, samples, depth)
    h = rig.rock_height_m + rig.grid_depth_m / ICE_REFRACTIVE_INDEX
    H = h * s / (s - 1.0) if s > 1.0 else np.inf
    lo, hi = HEIGHT_RANGE_M
    values = {"layout_scale": s, "camera_height_m": H if np.isfinite(H) else None,
              "rig_camera_height_m": rig.camera_height_m}
    layout_hint = ("the marker layout ([[markers]] x_m/y_m) or [rock].height_m may be wrong")
    if not np.isfinite(H) or not lo <= H <= hi:
        rep.checks.append(Check(
            "camera_height", "warn", f"parallax implies {H:.2f} m (markers look "
            f"{(s - 1) * 100:+.1f} % larger than on the ice)", f"implausible: {layout_hint}",
            values))
    elif rig.camera_height_m is not None and abs(H - rig.camera_height_m) > max(
            0.3, 0.2 * rig.camera_height_m):
        rep.checks.append(Check(
            "camera_height", "warn", f"parallax implies {H:.2f} m, the rig says "
            f"{rig.camera_height_m:g} m", f"check [camera].height_m; or {layout_hint}",
            values))
    else:
        rep.checks.append(Check("camera_height", "ok", f"about {H:.2f} m from the "
                                f"parallax over {scales.size} frame(s)", values=values))


def _scale_resolution_check(rep, rig, samples, depth: float) -> None:
    """How finely the rock's rulers check the grid's scale on these frames (what
    ``track`` records as ``scale_check_resolution``; it warns on the same limit)."""
    from .track.outline import scale_check_resolution

    res = scale_check_resolution([x["scale"] for _, x in samples],
                                 [x["outline_scale"] for _, x in samples], rig,
                                 rig.rock_height_m + depth, depth)
    text = (f"the grid's scale is checked against the rock to +-{100 * res:.1f} %"
            if np.isfinite(res) else "the grid's scale cannot be checked against the rock")
    if res <= rig.tracking.scale_resolution_warn:
        rep.checks.append(Check("grid_scale", "ok", text, values={"resolution": res}))
        return
    rep.checks.append(Check(
        "grid_scale", "warn", text,
        "a grid spacing off by less is not caught (every position and speed would be off "
        "by as much): measure the thread spacing over several cells"
        + ("" if rig.camera_height_m is not None else " and give [camera].height_m"),
        {"resolution": res if np.isfinite(res) else None}))
