"""Dynamic Window Approach local planner (Fox, Burgard, Thrun 1997), dwa_local_planner style."""
import math

import numpy as np
from scipy.spatial import cKDTree

from .costmap import INSCRIBED
from .geometry import wrap_angle


class DWAConfig:
    """Limits and weights; names follow dwa_local_planner where one exists."""

    def __init__(self, max_vel_x=0.4, max_vel_theta=1.0, acc_lim_x=0.5, acc_lim_theta=1.5,
                 sim_time=1.5, sim_granularity=0.1, vx_samples=8, vth_samples=21,
                 control_period=0.1, path_distance_bias=1.0, goal_distance_bias=1.5,
                 occdist_scale=0.5, heading_bias=0.3, robot_radius=0.3, obstacle_margin=0.05):
        self.__dict__.update(locals())
        del self.__dict__["self"]


def scan_obstacle_points(sensor_pose, ranges, angle_min, angle_increment, range_min,
                         max_range=3.0):
    """(N, 2) points, in the frame sensor_pose is given in, of the laser returns between
    range_min and max_range: the obstacles choose_velocity checks the arcs against. Every second
    return is kept, which halves the KD-tree's work."""
    x, y, th = sensor_pose
    r = np.asarray(ranges)
    a = angle_min + np.arange(len(r)) * angle_increment
    ok = np.isfinite(r) & (r < max_range) & (r > range_min)
    pts = np.column_stack([x + r[ok] * np.cos(th + a[ok]), y + r[ok] * np.sin(th + a[ok])])
    return pts[::2]


def rotate_in_place_rate(target_yaw, yaw, max_w):
    """Turn rate towards target_yaw: proportional to the error, at least 0.2 rad/s, at most
    max_w; 0 within 0.05 rad."""
    err = float(wrap_angle(target_yaw - yaw))
    return math.copysign(min(max_w, max(0.2, 1.5 * abs(err))), err) if abs(err) > 0.05 else 0.0


def window_samples(v, w, cfg, max_v, max_w):
    """Velocity pairs reachable within one control period under the acceleration limits."""
    dt = max(cfg.control_period, 0.1)
    v_lo, v_hi = max(0.0, v - cfg.acc_lim_x * dt), min(max_v, v + cfg.acc_lim_x * dt)
    w_lo, w_hi = max(-max_w, w - cfg.acc_lim_theta * dt), min(max_w, w + cfg.acc_lim_theta * dt)
    v_hi, w_hi = max(v_hi, v_lo), max(w_hi, w_lo)
    vs = np.linspace(v_lo, v_hi, cfg.vx_samples)
    ws = np.linspace(w_lo, w_hi, cfg.vth_samples)
    vv, ww = np.meshgrid(vs, ws, indexing="ij")
    return vv.ravel(), ww.ravel()


def rollout(pose, vs, ws, sim_time, step):
    """Poses along constant-(v, w) arcs: arrays (samples, steps) of x, y, yaw."""
    t = np.arange(1, int(round(sim_time / step)) + 1) * step
    th = pose[2] + ws[:, None] * t[None, :]
    straight = np.abs(ws) < 1e-6
    wsafe = np.where(straight, 1.0, ws)[:, None]
    x = np.where(straight[:, None], pose[0] + vs[:, None] * t * math.cos(pose[2]),
                 pose[0] + vs[:, None] / wsafe * (np.sin(th) - math.sin(pose[2])))
    y = np.where(straight[:, None], pose[1] + vs[:, None] * t * math.sin(pose[2]),
                 pose[1] - vs[:, None] / wsafe * (np.cos(th) - math.cos(pose[2])))
    return x, y, th


def local_goal(path, pose, lookahead):
    """The path point lookahead metres (along the path) past the point nearest the robot."""
    d = np.hypot(path[:, 0] - pose[0], path[:, 1] - pose[1])
    i = int(np.argmin(d))
    seg = np.hypot(*np.diff(path[i:], axis=0).T) if len(path) - i > 1 else np.zeros(0)
    along = np.concatenate([[0.0], np.cumsum(seg)])
    j = i + int(np.searchsorted(along, lookahead))
    return path[min(j, len(path) - 1)], i


def choose_velocity(pose, vel, path, costmap, obstacles, cfg, max_v=None, max_w=None,
                    lookahead=1.5):
    """Best (v, w, scores-ok) for following path; (0, 0, False) when every arc collides.

    costmap: (cost grid, resolution, origin) of the static inflated map; obstacles: (N, 2)
    laser points in the same frame, for things the map does not have.
    """
    max_v = cfg.max_vel_x if max_v is None else max_v
    max_w = cfg.max_vel_theta if max_w is None else max_w
    vs, ws = window_samples(vel[0], vel[1], cfg, max_v, max_w)
    x, y, th = rollout(pose, vs, ws, cfg.sim_time, cfg.sim_granularity)
    cost, res, origin = costmap
    col = np.clip(((x - origin[0]) / res).astype(int), 0, cost.shape[1] - 1)
    row = np.clip(((y - origin[1]) / res).astype(int), 0, cost.shape[0] - 1)
    static = cost[row, col].astype(float)
    valid = static.max(axis=1) < INSCRIBED
    occ = static.max(axis=1) / 252.0
    if obstacles is not None and len(obstacles):
        clear, _ = cKDTree(obstacles).query(np.column_stack([x.ravel(), y.ravel()]))
        clear = clear.reshape(x.shape).min(axis=1)
        valid &= clear > cfg.robot_radius + cfg.obstacle_margin
        occ = np.maximum(occ, np.exp(-3.0 * np.maximum(clear - cfg.robot_radius, 0.0)))
    if not valid.any():
        return 0.0, 0.0, False
    goal, _ = local_goal(path, pose, lookahead)
    ex, ey, eth = x[:, -1], y[:, -1], th[:, -1]
    path_d, _ = cKDTree(path).query(np.column_stack([ex, ey]))
    goal_d = np.hypot(goal[0] - ex, goal[1] - ey)
    heading = np.abs(wrap_angle(np.arctan2(goal[1] - ey, goal[0] - ex) - eth))
    score = (cfg.path_distance_bias * path_d + cfg.goal_distance_bias * goal_d
             + cfg.occdist_scale * occ + cfg.heading_bias * heading)
    score[~valid] = np.inf
    k = int(np.argmin(score))
    return float(vs[k]), float(ws[k]), True
