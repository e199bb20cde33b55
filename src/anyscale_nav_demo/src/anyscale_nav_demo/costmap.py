"""Inflated costmap (costmap_2d's inflation layer) and a Dijkstra navigation function."""
import math

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

LETHAL, INSCRIBED = 254, 253


def inflate(occupied, unknown, resolution, inscribed_radius, inflation_radius, cost_scaling):
    """costmap_2d costs: 254 on obstacles, 253 within the robot's radius, then
    252 * exp(-cost_scaling * (d - inscribed_radius)) out to inflation_radius, else 0.
    Unknown cells are lethal: the planner never routes through unmapped space."""
    dist = ndimage.distance_transform_edt(~occupied) * resolution
    cost = np.where(dist <= inflation_radius,
                    252.0 * np.exp(-cost_scaling * np.maximum(dist - inscribed_radius, 0.0)), 0.0)
    cost = cost.astype(np.uint8)
    cost[dist <= inscribed_radius] = INSCRIBED
    cost[occupied | unknown] = LETHAL
    return cost


def downsample_max(cost, factor):
    """Coarser grid keeping each block's worst cost (a cell is as bad as its worst part)."""
    if factor <= 1:
        return cost
    h, w = (cost.shape[0] // factor) * factor, (cost.shape[1] // factor) * factor
    return cost[:h, :w].reshape(h // factor, factor, w // factor, factor).max(axis=(1, 3))


def grid_graph(cost, resolution, cost_factor):
    """Sparse 8-connected graph over traversable cells; an edge costs its length times
    (1 + cost_factor * mean cell cost / 252), so paths keep away from walls."""
    h, w = cost.shape
    ok = cost < INSCRIBED
    idx = np.arange(h * w).reshape(h, w)
    rows, cols, weights = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = (slice(0, h - dr), slice(max(0, -dc), w - max(0, dc)))
        b = (slice(dr, h), slice(max(0, dc), w + min(0, dc)))
        both = ok[a] & ok[b]
        length = resolution * math.hypot(dr, dc)
        pair_cost = cost[a][both].astype(float) + cost[b][both]
        wgt = length * (1.0 + cost_factor * pair_cost / (2 * 252.0))
        rows += [idx[a][both], idx[b][both]]
        cols += [idx[b][both], idx[a][both]]
        weights += [wgt, wgt]
    return csr_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(h * w, h * w))


class NavigationFunction:
    """Cost-to-goal from every cell (one Dijkstra from the goal): any start's path is then a
    walk down the predecessors, so replanning as the robot moves costs nothing."""

    def __init__(self, cost, resolution, origin, graph, goal_xy):
        self.cost, self.res, self.origin = cost, resolution, origin
        self.shape = cost.shape
        gc = self.to_cell(goal_xy)
        goal = self.nearest_traversable(gc)
        if goal is None:
            raise ValueError("goal %s is not in traversable space" % (goal_xy,))
        self.goal_cell = goal
        self.dist, self.pred = dijkstra(graph, directed=True,
                                        indices=goal[0] * self.shape[1] + goal[1],
                                        return_predecessors=True)

    def to_cell(self, xy):
        return (int((xy[1] - self.origin[1]) / self.res), int((xy[0] - self.origin[0]) / self.res))

    def to_world(self, r, c):
        return (self.origin[0] + (c + 0.5) * self.res, self.origin[1] + (r + 0.5) * self.res)

    def nearest_traversable(self, rc, radius_cells=20):
        """The traversable cell closest to rc (the robot may stand in an inflated zone)."""
        r0, c0 = rc
        h, w = self.shape
        r_lo, r_hi = max(0, r0 - radius_cells), min(h, r0 + radius_cells + 1)
        c_lo, c_hi = max(0, c0 - radius_cells), min(w, c0 + radius_cells + 1)
        if r_lo >= r_hi or c_lo >= c_hi:
            return None
        win = self.cost[r_lo:r_hi, c_lo:c_hi] < INSCRIBED
        if not win.any():
            return None
        rr, cc = np.nonzero(win)
        k = np.argmin((rr + r_lo - r0) ** 2 + (cc + c_lo - c0) ** 2)
        return (int(rr[k] + r_lo), int(cc[k] + c_lo))

    def path_from(self, xy):
        """World waypoints from xy to the goal, or None when the goal cannot be reached."""
        start = self.nearest_traversable(self.to_cell(xy))
        if start is None:
            return None
        node = start[0] * self.shape[1] + start[1]
        if not np.isfinite(self.dist[node]):
            return None
        cells = [node]
        while self.pred[node] >= 0:
            node = self.pred[node]
            cells.append(node)
        r, c = np.divmod(np.asarray(cells), self.shape[1])
        wx, wy = self.to_world(r, c)
        return np.column_stack([wx, wy])
