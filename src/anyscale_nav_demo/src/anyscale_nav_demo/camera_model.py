"""Pinhole camera intrinsics (numpy only, so the camera driver need not load OpenCV)."""
import math

import numpy as np


class PinholeCamera:
    """Intrinsics of an undistorted camera; image width/height in pixels, horizontal FOV."""

    def __init__(self, width=192, height=144, hfov=math.radians(58.0)):
        self.width, self.height = width, height
        f = (width / 2.0) / math.tan(hfov / 2.0)
        self.K = np.array([[f, 0, width / 2.0], [0, f, height / 2.0], [0, 0, 1.0]])
        self.D = np.zeros(5)

    def project(self, pts_optical):
        """Pixel coordinates of points given in the optical frame (z forward, x right, y down)."""
        p = np.asarray(pts_optical, dtype=float)
        return np.column_stack([self.K[0, 0] * p[:, 0] / p[:, 2] + self.K[0, 2],
                                self.K[1, 1] * p[:, 1] / p[:, 2] + self.K[1, 2]])
