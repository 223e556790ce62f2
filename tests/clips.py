"""Short rendered clips with a random set-up, for tests of the tracker's decisions."""

from dataclasses import replace

from curltrack.physics.shot import ShotModel
from curltrack.rig import default_rig
from curltrack.simulate import simulate_series


def render_clip(path, rng, n_frames: int = 70, occlusion: bool = False, **config):
    """A clip of the first ``n_frames`` of a random draw (v0 0.8-1.6 m/s, either spin),
    ladder or handheld, written to ``path``; returns the rig.  640x360, 2 blur sub-frames
    and OpenCV's mp4v unless ``config`` (other :class:`curltrack.render.RenderConfig`
    fields: ``width``, ``encoding``, ...) says otherwise."""
    from curltrack.render import CameraConfig, RenderConfig, render_video

    rig = default_rig()
    sim = simulate_series(ShotModel(v0=rng.uniform(0.8, 1.6),
                                    omega0=rng.choice([-1, 1]) * rng.uniform(0.5, 2.0)), fps=30)
    sim = replace(sim, data=sim.data.iloc[:n_frames].reset_index(drop=True))
    config = {"width": 640, "height": 360, "blur_subframes": 2, **config}
    render_video(sim, rig, path, config=RenderConfig(
        camera=CameraConfig(motion=str(rng.choice(["ladder", "handheld"]))),
        occlusion=occlusion, **config), seed=int(rng.integers(1 << 30)))
    return rig
