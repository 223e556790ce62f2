"""What the frames look like: threads where the rig puts them, thin and faint; the rock's
size; the sensor noise level."""

from __future__ import annotations

import numpy as np
import pytest

from render.shots import closed_form_shot
from curltrack.rig import default_rig
from curltrack.render import CameraConfig, Production, RenderConfig


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


def _thread_profile(img, cam, X, Ys, depth_z, half=6):
    """Mean brightness across the thread at world X (running along Y), vs offset (px)."""
    gray = img.astype(float).mean(axis=2)
    prof = []
    for Y in Ys:
        p0, p1 = cam.project([[X, Y, depth_z], [X + 0.001, Y, depth_z]])
        n = (p1 - p0) / np.linalg.norm(p1 - p0)  # image direction across the thread
        offs = np.arange(-half, half + 1)
        pts = p0 + offs[:, None] * n
        u, v = np.round(pts).astype(int).T
        if (u < 0).any() or (v < 0).any() or (u >= img.shape[1]).any() or (v >= img.shape[0]).any():
            continue
        # bilinear sampling at the exact positions
        x0, y0 = np.floor(pts).astype(int).T
        fx, fy = (pts - np.floor(pts)).T
        g = (gray[y0, x0] * (1 - fx) * (1 - fy) + gray[y0, x0 + 1] * fx * (1 - fy)
             + gray[y0 + 1, x0] * (1 - fx) * fy + gray[y0 + 1, x0 + 1] * fx * fy)
        prof.append(g)
    return np.arange(-half, half + 1), np.mean(prof, axis=0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_threads_are_where_the_rig_says_thin_and_faint(seed):
    rng = np.random.default_rng(seed)
    rig = default_rig()
    shot = closed_form_shot(y_F=0.0, t_F=1.0, theta_F=1.0, duration=0.1)
    cfg = RenderConfig(camera=CameraConfig(height_m=float(rng.uniform(1.5, 3.0)),
                                           tilt_deg=float(rng.uniform(0, 3))),
                       read_noise=0.0, shot_noise_gain=0.0, jpeg_quality=None, flicker=0.0)
    prod = Production(shot, rig, cfg, seed=seed)
    img, info = next(prod.frames(0, 1))
    st = prod.settings()
    # a thread running along Y at X = phase_x * spacing (+ k spacing), world frame
    X = st["lattice_phase"][0] * rig.spacing_x_m + 2 * rig.spacing_x_m
    Ys = np.linspace(-0.6, 0.6, 25)
    Ys = Ys[np.abs(Ys) > 0.3]  # off the rock and its shadow
    off, prof = _thread_profile(img, info.camera, X, Ys, prod.tex_z_m)
    ice = np.median(np.r_[prof[:3], prof[-3:]])
    dip = ice - prof
    k = int(np.argmax(dip))
    assert abs(off[k]) <= 1, f"thread drawn {off[k]} px from where the rig and camera put it"
    centre = (dip[k - 1:k + 2] * off[k - 1:k + 2]).sum() / dip[k - 1:k + 2].sum()
    assert abs(centre) < 0.35
    assert 0.05 < dip[k] / ice < 0.45  # low contrast
    width = (dip > dip[k] / 2).sum()  # px above half depth
    assert 1 <= width <= 3


def test_rock_size_and_parallax_at_default_camera():
    shot = closed_form_shot(y_F=0.0, t_F=1.0, theta_F=1.0, duration=0.1)
    prod = Production(shot, default_rig(), RenderConfig(read_noise=0.0, shot_noise_gain=0.0,
                                                        jpeg_quality=None), seed=3)
    img, info = next(prod.frames(0, 1))
    row = prod.truth().data.iloc[0]
    gray = img.astype(float).mean(axis=2)
    u, v = int(row["u_top_px"]), int(row["v_top_px"])
    win = gray[v - 80:v + 80, u - 80:u + 80]
    dark = win < 0.75 * np.median(gray)
    diameter = 2 * np.sqrt(dark.sum() / np.pi)
    assert 60 < diameter < 120  # the brief: ~60-120 px across at 960x540
    # parallax: raised points are drawn away from the nadir (the image of the point of
    # the ice below the lens), by the factor H / (H - h)
    cam = info.camera
    nadir = cam.project([[cam.C[0], cam.C[1], 0.0]])[0]
    d_top = np.hypot(row["u_top_px"] - nadir[0], row["v_top_px"] - nadir[1])
    d_ice = np.hypot(row["u_px"] - nadir[0], row["v_px"] - nadir[1])
    H, h = cam.C[2], default_rig().rock_height_m
    assert d_top / d_ice == pytest.approx(H / (H - h), rel=0.02)


@pytest.mark.parametrize("demosaic", [False, True])
def test_sensor_noise_level(demosaic):
    """Noise RMS = sqrt(read^2 + gain I); with the Bayer sensor it is per photosite, seen
    unchanged at the photosites of each colour (the green ones are checked)."""
    shot = closed_form_shot(y_F=0.0, t_F=1.0, theta_F=1.0, duration=0.1)
    base = dict(jpeg_quality=None, flicker=0.0, demosaic=demosaic)
    quiet = next(Production(shot, default_rig(), RenderConfig(read_noise=0.0, shot_noise_gain=0.0,
                                                             **base), seed=5).frames(0, 1))[0]
    noisy = next(Production(shot, default_rig(), RenderConfig(read_noise=3.0, shot_noise_gain=0.1,
                                                             **base), seed=5).frames(0, 1))[0]
    diff = noisy.astype(float) - quiet.astype(float)
    level = quiet.astype(float)
    if demosaic:  # green photosites: even rows, odd columns (B G / G R cells)
        diff, level = diff[0::2, 1::2, 1], level[0::2, 1::2, 1]
    sel = (level > 120) & (level < 250)
    expected = np.sqrt(3.0**2 + 0.1 * level[sel]).mean()
    assert abs(diff[sel].mean()) < 0.2
    assert diff[sel].std() == pytest.approx(expected, rel=0.15)


def test_painted_house_where_asked():
    from curltrack.render import IceStyle

    shot = closed_form_shot(y_F=0.0, t_F=1.0, theta_F=1.0, duration=0.1)
    cfg = RenderConfig(ice=IceStyle(house_at_m=0.0, sheet_lines=True), read_noise=0.0,
                       shot_noise_gain=0.0, jpeg_quality=None, glare=0.0)
    prod = Production(shot, default_rig(), cfg, seed=4)
    img, info = next(prod.frames(0, 1))
    rot = np.deg2rad(prod.settings()["truth_rotation_deg"])
    z = prod.tex_z_m
    for r, channel in ((0.4, 2), (1.5, 0)):  # 4-ft ring red (BGR index 2), 12-ft blue (0)
        for ang in np.deg2rad([30, 150, 250]):
            X, Y = _rot(rot) @ [r * np.cos(ang), r * np.sin(ang)]
            u, v = np.round(info.camera.project([[X, Y, z]])[0]).astype(int)
            if 0 <= u < img.shape[1] and 0 <= v < img.shape[0]:
                px = img[v, u].astype(int)
                assert px[channel] > max(np.delete(px, channel)) + 30, (r, px)
