"""Run results: time to complete, path length, localisation error, mean angular velocity, and
the paper's Fig. 5 configurations (where AMCL and AR recognition run) along the path."""
import bisect
import csv
import math

import numpy as np

# Fig. 5's four configurations (the paper's colours), by where the demo's two migratable nodes
# run: AMCL and AR recognition, each on the robot (the master scale) or away from it.
AMCL_ON_LAPTOP = "AMCL on laptop"           # green
BOTH_ON_ROBOT = "both on robot"             # red
BOTH_ON_LAPTOP = "both on laptop"           # blue
AR_ON_LAPTOP = "AR only on laptop"          # yellow
CONFIGURATIONS = (AMCL_ON_LAPTOP, BOTH_ON_ROBOT, BOTH_ON_LAPTOP, AR_ON_LAPTOP)
CONFIGURATION_COLOURS = {AMCL_ON_LAPTOP: "#1fa833", BOTH_ON_ROBOT: "#d91a1a",
                         BOTH_ON_LAPTOP: "#2659f2", AR_ON_LAPTOP: "#f2d91a"}


def configuration_of(mapping, master="robot", amcl="amcl", ar="ar_recognition"):
    """Which of Fig. 5's configurations a mapping {node: scale} is (a node the mapping does
    not name runs on the master: the start)."""
    amcl_out = mapping.get(amcl, master) != master
    ar_out = mapping.get(ar, master) != master
    return {(True, False): AMCL_ON_LAPTOP, (False, False): BOTH_ON_ROBOT,
            (True, True): BOTH_ON_LAPTOP, (False, True): AR_ON_LAPTOP}[(amcl_out, ar_out)]


def configurations_at(times, changes, master="robot"):
    """The configuration at each time from `changes`, [(t, mapping)] in time order (before the
    first change every node is on the master)."""
    starts = [t for t, _ in changes]
    out = []
    for t in times:
        i = bisect.bisect_right(starts, t) - 1
        out.append(configuration_of(changes[i][1] if i >= 0 else {}, master))
    return out


def configuration_runs(xy, configurations):
    """Consecutive runs of one configuration along a path: [(configuration, (M, 2) points)],
    each run sharing its first point with the end of the previous one so the line is whole."""
    xy = np.asarray(xy, dtype=float)
    runs, start = [], 0
    for i in range(1, len(configurations) + 1):
        if i == len(configurations) or configurations[i] != configurations[start]:
            runs.append((configurations[start], xy[max(0, start - 1):i]))
            start = i
    return runs


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


def plot_path(png_path, occ_map, truth, estimate, title="", configurations=None):
    """PNG of the true and estimated paths over the map; with `configurations` (one per truth
    row, see configurations_at) the true path is coloured by Fig. 5's configuration."""
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
    if len(truth) and configurations:
        shown = set()
        for configuration, points in configuration_runs(truth[:, 1:3], configurations):
            ax.plot(points[:, 0], points[:, 1], "-", lw=1.5,
                    color=CONFIGURATION_COLOURS[configuration],
                    label=None if configuration in shown else f"ground truth, {configuration}")
            shown.add(configuration)
    elif len(truth):
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
