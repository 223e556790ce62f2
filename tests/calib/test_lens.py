"""Lens model: our distort/undistort agree with OpenCV's and invert each other."""

import cv2
import numpy as np
import pytest

from curltrack.calib.lens import apply_h, camera_matrix, distort, undistort


@pytest.mark.parametrize("seed", range(4))
def test_distortion_matches_opencv_and_inverts(seed):
    rng = np.random.default_rng(seed)
    K = camera_matrix(960, 540, rng.uniform(400, 1200))
    K[:2, 2] += rng.uniform(-20, 20, 2)
    dist = (rng.uniform(-0.3, 0.1), rng.uniform(-0.05, 0.05), 0.0, 0.0, 0.0)
    p = np.column_stack([rng.uniform(0, 959, 200), rng.uniform(0, 539, 200)])
    d = distort(p, K, dist)
    q = (p - K[:2, 2]) / K[0, 0]
    ref, _ = cv2.projectPoints(np.column_stack([q, np.ones(len(q))]), np.zeros(3), np.zeros(3),
                               K, np.asarray(dist))
    np.testing.assert_allclose(d, ref[:, 0], atol=1e-3)  # OpenCV works in float32
    np.testing.assert_allclose(undistort(d, K, dist), p, atol=1e-4)


def test_apply_h_is_projective():
    H = np.array([[2.0, 0.1, 3.0], [0.2, 1.5, -1.0], [1e-3, 2e-3, 1.0]])
    p = np.array([[10.0, 20.0], [-5.0, 7.0]])
    x = np.column_stack([p, np.ones(2)]) @ H.T
    np.testing.assert_allclose(apply_h(H, p), x[:, :2] / x[:, 2:])
