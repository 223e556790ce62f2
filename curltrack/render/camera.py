"""Pinhole camera with radial lens distortion, and the camera paths of a recording.

Conventions
-----------
World ("ice") frame: X, Y on the ice surface along the rig's thread lattice (X across the
rink, Y along it), Z up, metres; right-handed.  Camera frame: x right in the image, y down
in the image, z along the optical axis (looking down at the ice).  Pixel coordinates
``(u, v)``: u to the right, v down, the *centre* of pixel (0, 0) at (0, 0) (OpenCV).

Projection of a world point ``P``::

    p_c = R (P - C);  x = p_c[0]/p_c[2];  y = p_c[1]/p_c[2];  r2 = x^2 + y^2
    d = 1 + k1 r2 + k2 r2^2;  u = fx x d + cx;  v = f y d + cy

(``k1 < 0`` is barrel distortion), with ``fx = f / pixel_aspect`` (non-square pixels: NTSC
DV's are 10:11, narrower than tall).  The ``fisheye`` lens is equidistant, as OpenCV's
``cv2.fisheye`` model: ``a = atan(r)``, ``a_d = a (1 + k1 a^2 + k2 a^4)`` and the distorted
point is ``(x, y) a_d / r``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError

LENSES = ("radial", "fisheye")


def rotation_matrix(rvec) -> np.ndarray:
    """Rotation matrix of a rotation vector (axis * angle, rad), Rodrigues' formula."""
    rvec = np.asarray(rvec, dtype=float)
    theta = float(np.linalg.norm(rvec))
    if theta < 1e-15:
        return np.eye(3)
    k = rvec / theta
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


def base_rotation(yaw_rad: float) -> np.ndarray:
    """World -> camera rotation of a camera looking straight down.

    ``yaw_rad`` is the world direction of the image's +u (right) axis, counter-clockwise
    from world +X seen from above.
    """
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with radial distortion at one pose.

    Parameters
    ----------
    f_px : float
        Focal length (px).
    cx, cy : float
        Principal point (px, pixel-centre convention).
    width, height : int
        Image size (px).
    R : (3, 3) array
        World -> camera rotation.
    C : (3,) array
        Camera centre in the world (m); ``C[2]`` is the lens height above the ice.
    k1, k2 : float
        Distortion coefficients: of r^2 and r^4 (``radial``, r in focal-length units) or
        of a^2 and a^4 (``fisheye``, a = the ray's angle off the axis, rad).
    pixel_aspect : float
        Pixel width / height (1 = square; NTSC DV 10/11): ``fx = f_px / pixel_aspect``.
    lens : {"radial", "fisheye"}
        Brown's radial polynomial, or the equidistant fisheye (OpenCV's model).
    """

    f_px: float
    cx: float
    cy: float
    width: int
    height: int
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    C: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 2.0]))
    k1: float = 0.0
    k2: float = 0.0
    pixel_aspect: float = 1.0
    lens: str = "radial"

    @property
    def fx(self) -> float:
        """Horizontal focal length (px)."""
        return self.f_px / self.pixel_aspect

    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix (px)."""
        return np.array([[self.fx, 0, self.cx], [0, self.f_px, self.cy], [0, 0, 1.0]])

    def to_normalized(self, uv) -> np.ndarray:
        """Pixel positions (N, 2) -> distorted normalised coordinates (N, 2)."""
        uv = np.asarray(uv, dtype=float)
        return (uv - np.array([self.cx, self.cy])) / np.array([self.fx, self.f_px])

    def to_pixels(self, xy) -> np.ndarray:
        """Normalised coordinates (N, 2) (distorted or not) -> pixel positions (N, 2)."""
        return np.asarray(xy, dtype=float) * np.array([self.fx, self.f_px]) + [self.cx,
                                                                               self.cy]

    def to_camera(self, points) -> np.ndarray:
        """World points (N, 3) (m) -> camera-frame points (N, 3) (m)."""
        P = np.atleast_2d(np.asarray(points, dtype=float))
        return (P - np.asarray(self.C)) @ np.asarray(self.R).T

    def normalized(self, points) -> np.ndarray:
        """World points (N, 3) -> undistorted normalised image coordinates (N, 2)."""
        pc = self.to_camera(points)
        if (pc[:, 2] <= 0).any():
            raise ParameterError("a point lies behind the camera")
        return pc[:, :2] / pc[:, 2:3]

    def distort(self, xy) -> np.ndarray:
        """Undistorted normalised coordinates (N, 2) -> distorted normalised (N, 2)."""
        xy = np.asarray(xy, dtype=float)
        r2 = (xy**2).sum(axis=-1, keepdims=True)
        if self.lens == "fisheye":
            r = np.sqrt(r2)
            a = np.arctan(r)
            ad = a * (1.0 + self.k1 * a**2 + self.k2 * a**4)
            return xy * np.divide(ad, r, out=np.ones_like(r), where=r > 0)
        return xy * (1.0 + self.k1 * r2 + self.k2 * r2**2)

    def undistort(self, xy_d, iterations: int = 12) -> np.ndarray:
        """Distorted normalised coordinates -> undistorted (Newton's method on the radius).

        Raises
        ------
        ParameterError
            If the distortion is not monotonic out to the requested radius.
        """
        xy_d = np.asarray(xy_d, dtype=float)
        rd = np.sqrt((xy_d**2).sum(axis=-1))
        r = rd.copy()  # radial: r; fisheye: the angle a (Newton on the same polynomial)
        for _ in range(iterations):
            f = r * (1.0 + self.k1 * r**2 + self.k2 * r**4) - rd
            df = 1.0 + 3.0 * self.k1 * r**2 + 5.0 * self.k2 * r**4
            if (df <= 0).any():
                raise ParameterError("lens distortion folds over inside the image (k1, k2 "
                                     "too strong for this field of view)", where="camera.k1")
            r = r - f / df
        if self.lens == "fisheye":
            if (r >= np.deg2rad(80)).any():
                raise ParameterError("the fisheye sees beyond 80 deg off its axis: the "
                                     "pinhole canvas cannot hold it", where="camera.view_m")
            r = np.tan(r)
        scale = np.divide(r, rd, out=np.ones_like(rd), where=rd > 0)
        return xy_d * scale[..., None]

    def project(self, points) -> np.ndarray:
        """World points (N, 3) (m) -> distorted pixel coordinates (N, 2) (px)."""
        return self.to_pixels(self.distort(self.normalized(points)))

    def plane_homography(self, z_m: float) -> np.ndarray:
        """3x3 homography from (X, Y, 1) on the plane Z = ``z_m`` to *undistorted* px."""
        R = np.asarray(self.R)
        t = -R @ np.asarray(self.C)
        M = np.column_stack([R[:, 0], R[:, 1], R[:, 2] * z_m + t])
        return self.K @ M

    def in_image(self, uv, margin: float = 0.0) -> np.ndarray:
        """Boolean mask: pixel positions inside the image (by ``margin`` px)."""
        uv = np.atleast_2d(uv)
        return ((uv[:, 0] >= -0.5 + margin) & (uv[:, 0] <= self.width - 0.5 - margin)
                & (uv[:, 1] >= -0.5 + margin) & (uv[:, 1] <= self.height - 0.5 - margin))
