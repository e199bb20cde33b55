"""ArUco markers: render them into a simulated pinhole camera's image, and detect them
(cv2.aruco)."""
import math

import cv2
import numpy as np

from .camera_model import PinholeCamera  # noqa: F401  (re-exported for callers)

DICTIONARY = cv2.aruco.DICT_4X4_50
QUIET_ZONE = 0.25          # white margin around the black square, as a fraction of its side


def marker_texture(marker_id, pixels=60):
    """Grey image of the marker's black square with its white quiet zone around it."""
    d = cv2.aruco.Dictionary_get(DICTIONARY)
    inner = cv2.aruco.drawMarker(d, int(marker_id), pixels)
    m = int(round(pixels * QUIET_ZONE))
    return cv2.copyMakeBorder(inner, m, m, m, m, cv2.BORDER_CONSTANT, value=255)


def marker_corners_world(x, y, z, yaw, size):
    """Corners (TL, TR, BR, BL as a viewer facing the marker sees them) of a wall marker whose
    normal points along yaw. size includes the quiet zone when the caller adds it."""
    right = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    c = np.array([x, y, z])
    h = size / 2.0
    return np.array([c - right * h + up * h, c + right * h + up * h,
                     c + right * h - up * h, c - right * h - up * h])


def world_to_optical(pts, cam_x, cam_y, cam_z, cam_yaw):
    """World points into the optical frame of a level camera looking along cam_yaw."""
    d = np.asarray(pts, dtype=float) - np.array([cam_x, cam_y, cam_z])
    c, s = math.cos(cam_yaw), math.sin(cam_yaw)
    fwd = c * d[:, 0] + s * d[:, 1]
    left = -s * d[:, 0] + c * d[:, 1]
    return np.column_stack([-left, -d[:, 2], fwd])


def background(camera, wall=165, floor=95):
    """A plain corridor: wall above the horizon, floor below."""
    img = np.full((camera.height, camera.width), wall, dtype=np.uint8)
    img[camera.height // 2:, :] = floor
    return img


def render(camera, base_image, cam_pose, markers, textures, max_range=6.0):
    """Draw every marker facing the camera and in front of it; returns (image, ids drawn).

    cam_pose = (x, y, z, yaw); markers: dicts with id, x, y, z, yaw, size (the black square).
    Occlusion by walls is the caller's job (it has the map); here only geometry counts.
    """
    img = base_image.copy()
    drawn = []
    cx, cy, cz, cyaw = cam_pose
    for m in markers:
        to_cam = np.array([cx - m["x"], cy - m["y"]])
        dist = float(np.hypot(*to_cam))
        if dist > max_range or np.dot(to_cam, [math.cos(m["yaw"]), math.sin(m["yaw"])]) <= 0:
            continue  # too far, or we see the back of the wall
        outer = m["size"] * (1 + 2 * QUIET_ZONE)
        corners = world_to_optical(marker_corners_world(m["x"], m["y"], m["z"], m["yaw"], outer),
                                   cx, cy, cz, cyaw)
        if np.any(corners[:, 2] < 0.05):
            continue  # partly behind the camera
        px = camera.project(corners).astype(np.float32)
        if (px[:, 0].max() < 0 or px[:, 0].min() > camera.width or px[:, 1].max() < 0
                or px[:, 1].min() > camera.height):
            continue
        tex = textures[m["id"]]
        t = tex.shape[0]
        src = np.float32([[0, 0], [t, 0], [t, t], [0, t]])
        H = cv2.getPerspectiveTransform(src, px)
        cv2.warpPerspective(tex, H, (camera.width, camera.height), dst=img,
                            flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_TRANSPARENT)
        drawn.append(m["id"])
    return img, drawn


class MarkerDetector:
    """cv2.aruco detection plus each marker's pose in the camera's optical frame."""

    def __init__(self, camera_matrix, dist_coeffs, marker_size, detector_params=None):
        """detector_params: {name: value} of cv2.aruco.DetectorParameters fields set after
        this class's defaults (e.g. adaptiveThreshWinSizeMax/Step, the threshold sweep that
        dominates the cost per frame). ValueError for a name DetectorParameters lacks or a
        value of the wrong type."""
        self.dictionary = cv2.aruco.Dictionary_get(DICTIONARY)
        self.params = cv2.aruco.DetectorParameters_create()
        # The default (0.6) let a half-seen marker at a grazing angle decode as a wrong id in
        # a full office loop; the 4x4_50 dictionary leaves room for a stricter rate.
        self.params.errorCorrectionRate = 0.3
        for name, value in sorted((detector_params or {}).items()):
            if name.startswith("_") or not hasattr(self.params, name):
                raise ValueError("cv2.aruco.DetectorParameters has no field %r" % (name,))
            old = getattr(self.params, name)
            if isinstance(old, bool) or isinstance(value, bool):
                ok = isinstance(old, bool) and isinstance(value, bool)
            elif isinstance(old, int):
                ok = isinstance(value, int)
            else:
                ok = isinstance(value, (int, float))
            if not ok:
                raise ValueError("DetectorParameters.%s must be %s like %r, got %r"
                                 % (name, type(old).__name__, old, value))
            try:
                setattr(self.params, name, type(old)(value))
            except (TypeError, cv2.error) as e:
                raise ValueError("DetectorParameters.%s = %r: %s" % (name, value, e))
        self.K = np.asarray(camera_matrix, dtype=float).reshape(3, 3)
        self.D = np.asarray(dist_coeffs, dtype=float)
        self.size = marker_size

    def detect(self, grey):
        """[(id, tvec (3,), rotation matrix (3, 3))] for every marker found in the image."""
        corners, ids, _ = cv2.aruco.detectMarkers(grey, self.dictionary, parameters=self.params)
        if ids is None:
            return []
        rvecs, tvecs, _ = cv2.aruco.estimatePoseSingleMarkers(corners, self.size, self.K, self.D)
        out = []
        for i, r, t in zip(ids.ravel(), rvecs, tvecs):
            out.append((int(i), t.ravel(), cv2.Rodrigues(r.ravel())[0]))
        return out


def rotation_to_quaternion(R):
    """(x, y, z, w) of a rotation matrix."""
    R = np.asarray(R, dtype=float)
    r00, r11, r22 = R[0, 0], R[1, 1], R[2, 2]
    w = math.sqrt(max(0.0, 1.0 + r00 + r11 + r22)) / 2.0
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r00 - r11 - r22)) / 2.0, R[2, 1] - R[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r00 + r11 - r22)) / 2.0, R[0, 2] - R[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r00 - r11 + r22)) / 2.0, R[1, 0] - R[0, 1])
    return (x, y, z, w)
