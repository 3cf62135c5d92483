"""A pinhole camera: intrinsics from a field of view, a pose looking at a point, a 3x4 projection."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import as_array

__all__ = ["Camera", "look_at", "front_camera"]


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera.

    ``world_to_camera (4, 4)``: camera frame with +x right, +y up, looking down -z (OpenGL);
    ``vertical_fov`` in degrees; ``width``, ``height`` in pixels. Pixels have their origin at the
    top left of the image, +y down.
    """

    world_to_camera: np.ndarray
    vertical_fov: float
    width: int
    height: int

    def __post_init__(self):
        object.__setattr__(self, "world_to_camera", as_array(self.world_to_camera, "world_to_camera", shape=(4, 4)))
        if not 0 < self.vertical_fov < 180:
            raise ValueError(f"vertical_fov must be in (0, 180) degrees, got {self.vertical_fov}")
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")

    @property
    def focal(self) -> float:
        """Focal length in pixels."""
        return 0.5 * self.height / np.tan(0.5 * np.radians(self.vertical_fov))

    @property
    def projection(self) -> np.ndarray:
        """The 3x4 matrix ``P`` with ``[u*w, v*w, w] = P @ [x, y, z, 1]`` (u, v in pixels)."""
        K = np.array([[self.focal, 0, self.width / 2], [0, -self.focal, self.height / 2], [0, 0, 1.0]])
        flip = np.diag([1.0, 1.0, -1.0])  # the camera looks down -z; depth w = -z
        return K @ flip @ self.world_to_camera[:3]

    def project(self, points) -> np.ndarray:
        """Pixels ``(N, 2)`` of world points ``(N, 3)``."""
        points = as_array(points, "points", shape=("N", 3))
        h = np.c_[points, np.ones(len(points))] @ self.projection.T
        return h[:, :2] / h[:, 2:3]

    def unproject(self, pixels, distance) -> np.ndarray:
        """World points ``(N, 3)`` at ``distance (N,)`` along the viewing axis behind ``pixels (N, 2)``."""
        pixels = as_array(pixels, "pixels", shape=("N", 2))
        distance = np.asarray(distance, dtype=np.float64).reshape(-1)
        x = (pixels[:, 0] - self.width / 2) / self.focal * distance
        y = -(pixels[:, 1] - self.height / 2) / self.focal * distance
        camera_points = np.c_[x, y, -distance, np.ones(len(distance))]
        return (camera_points @ np.linalg.inv(self.world_to_camera).T)[:, :3]

    def gl_matrix(self, near: float, far: float) -> np.ndarray:
        """(4, 4) OpenGL clip transform (projection @ view) for depths between ``near`` and ``far``."""
        t = np.tan(0.5 * np.radians(self.vertical_fov))
        aspect = self.width / self.height
        P = np.array([[1 / (t * aspect), 0, 0, 0], [0, 1 / t, 0, 0],
                      [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)], [0, 0, -1, 0]])
        return P @ self.world_to_camera


def look_at(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """(4, 4) world-to-camera transform of a camera at ``eye`` looking at ``target``."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    R = np.stack([right, true_up, -forward])
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = -R @ eye
    return M


def front_camera(vertices, width: int, height: int, *, vertical_fov: float = 25.0, margin: float = 1.15,
                 yaw: float = 0.0) -> Camera:
    """A camera on the +z side of ``vertices (N, 3)`` (a face looking along +z), framing them all.

    ``yaw`` (degrees) turns the camera around the vertical axis through their centre.
    """
    v = as_array(vertices, "vertices", shape=("N", 3), min_length=1)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = np.linalg.norm(v - centre, axis=1).max() * margin
    fov = np.radians(min(vertical_fov, vertical_fov * width / height))
    distance = radius / np.sin(0.5 * fov)
    a = np.radians(yaw)
    eye = centre + distance * np.array([np.sin(a), 0.0, np.cos(a)])
    return Camera(look_at(eye, centre), vertical_fov, width, height)
