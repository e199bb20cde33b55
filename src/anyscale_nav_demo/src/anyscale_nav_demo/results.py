"""Run results: time to complete, path length, localisation error, mean angular velocity."""
import csv
import math

import numpy as np


def path_length(xy):
    xy = np.asarray(xy, dtype=float)
    return float(np.sum(np.hypot(*np.diff(xy, axis=0).T))) if len(xy) > 1 else 0.0


def mean_abs_angular_velocity_deg(t, yaw):
    """The paper's path-shape metric: mean |yaw rate| over the run, in degrees per second."""
    t, yaw = np.asarray(t, dtype=float), np.unwrap(np.asarray(yaw, dtype=float))
    if len(t) < 2 or t[-1] <= t[0]:
        return 0.0
    return float(np.sum(np.abs(np.diff(yaw))) / (t[-1] - t[0]) * 180.0 / math.pi)


def localisation_errors(truth_t, truth_xy, est_t, est_xy):
    """Position error of each estimate against ground truth interpolated at its time."""
    truth_t, truth_xy = np.asarray(truth_t), np.asarray(truth_xy)
    est_t, est_xy = np.asarray(est_t), np.asarray(est_xy)
    if len(truth_t) < 2 or len(est_t) == 0:
        return np.zeros(0)
    keep = (est_t >= truth_t[0]) & (est_t <= truth_t[-1])
    gx = np.interp(est_t[keep], truth_t, truth_xy[:, 0])
    gy = np.interp(est_t[keep], truth_t, truth_xy[:, 1])
    return np.hypot(est_xy[keep, 0] - gx, est_xy[keep, 1] - gy)


def summary(truth, estimate, started, finished, goals_reached, markers_seen):
    """Dict of the run's figures. truth/estimate: arrays of rows (t, x, y, yaw)."""
    truth, estimate = np.asarray(truth, dtype=float), np.asarray(estimate, dtype=float)
    err = localisation_errors(truth[:, 0], truth[:, 1:3], estimate[:, 0], estimate[:, 1:3]) \
        if len(truth) and len(estimate) else np.zeros(0)
    return {"time_to_complete_s": (finished - started) if finished else float("nan"),
            "path_length_m": path_length(truth[:, 1:3]) if len(truth) else 0.0,
            "loc_error_rms_m": float(np.sqrt(np.mean(err ** 2))) if len(err) else float("nan"),
            "loc_error_max_m": float(err.max()) if len(err) else float("nan"),
            "mean_angular_velocity_deg_s": mean_abs_angular_velocity_deg(truth[:, 0], truth[:, 3])
            if len(truth) else 0.0,
            "goals_reached": goals_reached, "markers_seen": markers_seen}


def write_csv(path, rows, header):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def plot_path(png_path, occ_map, truth, estimate, title=""):
    """PNG of the true and estimated paths over the map."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 7), dpi=100)
    img = np.where(occ_map.occupied, 0.0, np.where(occ_map.data < 0, 0.75, 1.0))
    h, w = img.shape
    x0, y0 = occ_map.origin[:2]
    ax.imshow(img, cmap="gray", origin="lower", vmin=0, vmax=1,
              extent=(x0, x0 + w * occ_map.resolution, y0, y0 + h * occ_map.resolution))
    truth, estimate = np.asarray(truth), np.asarray(estimate)
    if len(truth):
        ax.plot(truth[:, 1], truth[:, 2], "g-", lw=1.5, label="ground truth")
    if len(estimate):
        ax.plot(estimate[:, 1], estimate[:, 2], "r--", lw=1.0, label="EKF estimate")
    ax.legend(loc="upper right")
    ax.set_title(title)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    fig.tight_layout()
    fig.savefig(png_path)
    plt.close(fig)
