"""AMCL core: odometry motion model, likelihood-field sensor model, KLD resampling, recovery."""
import functools
import math

import numpy as np
from scipy import ndimage

from .geometry import wrap_angle


def obstacle_distances(occ_map, max_dist):
    """Distance (m) from every cell to the nearest occupied cell, capped at max_dist."""
    dist = ndimage.distance_transform_edt(~occ_map.occupied) * occ_map.resolution
    return np.minimum(dist, max_dist)


class LikelihoodField:
    """Distance (m) from every cell to the nearest occupied cell, capped (amcl's likelihood field).
    `dist`: those distances if already known (likelihood_cache), else computed here."""

    def __init__(self, occ_map, max_dist=2.0, dist=None):
        self.map = occ_map
        self.max_dist = max_dist
        self.dist = obstacle_distances(occ_map, max_dist) if dist is None else dist
        # A border of max_dist cells: points off the map clip onto it, so lookups need no mask.
        self.padded = np.pad(self.dist, 1, constant_values=max_dist)

    @functools.cached_property
    def free_xy(self):
        """Centres of the free cells: only random particles (recovery) need them."""
        free = np.argwhere(self.map.free)
        return np.column_stack(self.map.cell_center(free[:, 1], free[:, 0]))

    def distance_at(self, x, y):
        """Obstacle distance at world points; points off the map count as max_dist away."""
        col, row = self.map.world_to_cell(x, y)
        return self.padded[np.clip(row, -1, self.map.height) + 1,
                           np.clip(col, -1, self.map.width) + 1]


def sample_motion_diff(particles, d_odom, alphas, rng):
    """Move particles by the odometry increment between two odom-frame poses, decomposed as
    rot1-trans-rot2, with amcl's 'diff' noise model (Probabilistic Robotics, Table 5.6)."""
    (x0, y0, t0), (x1, y1, t1) = d_odom
    a1, a2, a3, a4 = alphas
    trans = math.hypot(x1 - x0, y1 - y0)
    rot1 = float(wrap_angle(math.atan2(y1 - y0, x1 - x0) - t0)) if trans > 0.01 else 0.0
    rot2 = float(wrap_angle(t1 - t0 - rot1))
    # Turning backwards by pi is the same move as driving backwards: use the smaller angle.
    rot1_n = min(abs(rot1), abs(float(wrap_angle(rot1 - math.pi))))
    rot2_n = min(abs(rot2), abs(float(wrap_angle(rot2 - math.pi))))
    n = len(particles)
    r1 = rot1 - rng.normal(0, math.sqrt(a1 * rot1_n ** 2 + a2 * trans ** 2), n)
    tr = trans - rng.normal(0, math.sqrt(a3 * trans ** 2 + a4 * (rot1_n ** 2 + rot2_n ** 2)), n)
    r2 = rot2 - rng.normal(0, math.sqrt(a1 * rot2_n ** 2 + a2 * trans ** 2), n)
    th = particles[:, 2] + r1
    particles[:, 0] += tr * np.cos(th)
    particles[:, 1] += tr * np.sin(th)
    particles[:, 2] = wrap_angle(th + r2)
    return particles


class BeamLikelihood:
    """amcl's likelihood-field weight of each particle for a scan: 1 + sum over beams of p(z)^3,
    p(z) = z_hit exp(-d^2 / 2 sigma_hit^2) + z_rand / range_max, d the distance from the beam's
    endpoint to the nearest obstacle.

    Computed in blocks of particles, in place, in buffers kept from scan to scan. The direct numpy
    form makes about eight particles x beams temporaries per scan (9 MB each at 5000 x 228), which
    glibc hands back to the kernel every time: faulting them in again cost more than the
    arithmetic (0.036 against 0.013 CPU-s a scan on the development machine), and a new process's
    first scan 3-4 times a later one, on the path of a node brought home to a starved robot.
    """

    BLOCK = 256             # particles per block: 256 x 341 beams x 8 bytes = 0.7 MB a buffer

    def __init__(self, field, sigma_hit, z_hit, z_rand):
        self.field = field
        self.sigma_hit, self.z_hit, self.z_rand = sigma_hit, z_hit, z_rand
        self.buffers = None

    def weights(self, particles, ranges, angles, laser_offset, range_max):
        ok = np.isfinite(ranges) & (ranges < range_max)
        r, a = ranges[ok], angles[ok]
        lx, ly, lt = laser_offset
        c, s = np.cos(particles[:, 2]), np.sin(particles[:, 2])
        px = particles[:, 0] + c * lx - s * ly         # the laser's position per particle
        py = particles[:, 1] + s * lx + c * ly
        beam_angles = lt + a
        grid, padded = self.field.map, self.field.padded
        out = np.empty(len(particles))
        for i in range(0, len(particles), self.BLOCK):
            j = min(i + self.BLOCK, len(particles))
            th, t, col, cell = self._buffers(j - i, len(r))
            np.add(particles[i:j, 2:3], beam_angles, out=th)
            self._axis_cells(np.cos(th, out=t), r, px[i:j], grid.origin[0], grid.width, col)
            self._axis_cells(np.sin(th, out=t), r, py[i:j], grid.origin[1], grid.height, cell)
            cell *= padded.shape[1]
            cell += col
            d = np.take(padded.ravel(), cell, out=t)
            d *= d
            d *= -0.5 / self.sigma_hit ** 2
            np.exp(d, out=d)
            d *= self.z_hit
            d += self.z_rand / range_max
            d **= 3
            out[i:j] = 1.0 + d.sum(axis=1)
        return out

    def _axis_cells(self, t, r, p, origin, size, cells):
        """Padded-grid index along one axis of the beam endpoints p + r t, t being the cosines
        or sines of the beams' angles (overwritten)."""
        t *= r
        t += p[:, None]
        t -= origin
        t /= self.field.map.resolution
        np.floor(t, out=t)
        np.clip(t, -1, size, out=t)
        t += 1
        np.copyto(cells, t, casting="unsafe")

    def _buffers(self, n, beams):
        if self.buffers is None or self.buffers[0].shape[1] != beams:
            shape = (self.BLOCK, beams)
            self.buffers = (np.empty(shape), np.empty(shape), np.empty(shape, dtype=np.intp),
                            np.empty(shape, dtype=np.intp))
        return tuple(b[:n] for b in self.buffers)


def moved_enough(odom_before, odom_now, min_distance, min_angle):
    """amcl's update_min_d / update_min_a rule: a filter update is due once the odometry moved
    min_distance metres or turned min_angle radians since the last update."""
    a, b = odom_before, odom_now
    return (math.hypot(b[0] - a[0], b[1] - a[1]) >= min_distance
            or abs(math.remainder(b[2] - a[2], 2 * math.pi)) >= min_angle)


def jump_beyond_odometry(last_pose, pose, odom_moved):
    """How much farther (m) the estimate moved between two updates than odometry did; 0 for
    the first estimate (last_pose None)."""
    if last_pose is None:
        return 0.0
    return math.hypot(pose[0] - last_pose[0], pose[1] - last_pose[1]) - odom_moved


def kld_sample_count(k, err, z, n_min, n_max):
    """Particles needed so the KL divergence to the true posterior stays below err (Fox 2003).

    One occupied bin needs n_min (amcl returns its maximum there, which only costs CPU: the
    bins cannot tell a tighter cloud apart anyway).
    """
    k = np.asarray(k, dtype=float)
    out = np.full(k.shape, float(n_min))
    many = k > 1
    km = k[many] - 1
    b = 2.0 / (9.0 * km)
    out[many] = np.ceil(km / (2 * err) * (1 - b + np.sqrt(b) * z) ** 3)
    return np.clip(out, n_min, n_max)


def _running_average(average, sample, alpha):
    """amcl's exponential average of the mean weight; 0 means none yet: the sample starts it."""
    return sample if average == 0 else average + alpha * (sample - average)


def systematic_resample(weights, n, rng):
    """Indices of n draws by low-variance (systematic) resampling."""
    cdf = np.cumsum(weights)
    cdf[-1] = 1.0
    u = (rng.random() + np.arange(n)) / n
    return np.searchsorted(cdf, u)


class ParticleFilter:
    """The adaptive Monte Carlo localisation filter, with amcl's parameter names and defaults."""

    def __init__(self, field, rng=None, min_particles=500, max_particles=5000, kld_err=0.01,
                 kld_z=0.99, alphas=(0.05, 0.05, 0.05, 0.05), sigma_hit=0.2, z_hit=0.95,
                 z_rand=0.05, range_max=5.6, recovery_alpha_slow=0.0, recovery_alpha_fast=0.0,
                 bin_size=(0.5, 0.5, math.radians(10)), hypothesis_switch_ratio=2.0,
                 exclude_occupied=True):
        self.field = field
        self.rng = rng or np.random.default_rng()
        self.min_particles, self.max_particles = min_particles, max_particles
        self.kld_err, self.kld_z = kld_err, kld_z
        self.alphas = alphas
        self.sensor = BeamLikelihood(field, sigma_hit, z_hit, z_rand)
        self.range_max = range_max
        self.alpha_slow, self.alpha_fast = recovery_alpha_slow, recovery_alpha_fast
        self.w_slow = self.w_fast = 0.0
        self.bin_size = np.asarray(bin_size)
        self.particles = np.zeros((0, 3))
        self.weights = np.zeros(0)
        self.switch_ratio = hypothesis_switch_ratio
        self.last_xy = None        # the last estimate's position; None after an initial pose
        self.exclude_occupied = exclude_occupied

    def init_gaussian(self, mean, cov_xx, cov_yy, cov_aa):
        """Scatter max(min_particles, ...) particles around a pose (amcl's initial pose)."""
        n = self.min_particles if self.min_particles > 0 else 100
        std = np.sqrt(np.maximum([cov_xx, cov_yy, cov_aa], 0.0))
        self.particles = np.asarray(mean, dtype=float) + self.rng.standard_normal((n, 3)) * std
        self.particles[:, 2] = wrap_angle(self.particles[:, 2])
        self.weights = np.full(n, 1.0 / n)
        self.w_slow = self.w_fast = 0.0
        self.last_xy = None

    def predict(self, odom_prev, odom_now):
        sample_motion_diff(self.particles, (odom_prev, odom_now), self.alphas, self.rng)

    def update(self, ranges, angles, laser_offset):
        """Weigh particles by a scan; also tracks the long/short-term likelihood averages."""
        p = self.sensor.weights(self.particles, ranges, angles, laser_offset, self.range_max)
        if self.exclude_occupied:
            # Not amcl's: a robot's centre is never inside a wall, but a particle there can fit
            # a scan as well as one in the corridor beside it (the likelihood field is 0 m from
            # an obstacle everywhere inside one). In a tolerance bench run 55 % of the cloud
            # lay in walls when the estimate jumped 1.25 m into them and the robot got lost.
            p = np.where(self.field.map.is_occupied_at(self.particles[:, 0],
                                                       self.particles[:, 1]), 0.0, p)
        w = self.weights * p
        total = w.sum()
        if not np.isfinite(total) or total <= 0:
            self.weights = np.full(len(p), 1.0 / len(p))
            return
        self.weights = w / total
        w_avg = float(np.mean(p))
        if self.alpha_slow > 0:
            self.w_slow = _running_average(self.w_slow, w_avg, self.alpha_slow)
            self.w_fast = _running_average(self.w_fast, w_avg, self.alpha_fast)

    def resample(self):
        """KLD-adaptive resampling with random injection when the fit drops (recovery)."""
        inject = 0.0
        if self.w_slow > 0:
            inject = max(0.0, 1.0 - self.w_fast / self.w_slow)
        cand = self.particles[systematic_resample(self.weights, self.max_particles, self.rng)]
        n_rand = self.rng.random(self.max_particles) < inject
        if n_rand.any() and len(self.field.free_xy):
            pick = self.field.free_xy[self.rng.integers(len(self.field.free_xy), size=n_rand.sum())]
            cand[n_rand, :2] = pick
            cand[n_rand, 2] = self.rng.uniform(-math.pi, math.pi, n_rand.sum())
        cand = cand[self.rng.permutation(len(cand))]
        n = self._kld_count(cand)
        self.particles = cand[:n].copy()
        self.weights = np.full(n, 1.0 / n)
        if inject > 0:   # amcl resets the averages after injecting, so it does not keep injecting
            self.w_slow = self.w_fast = 0.0

    def _kld_count(self, cand):
        keys = np.floor(cand / self.bin_size).astype(np.int64)
        _, first = np.unique(keys, axis=0, return_index=True)
        is_new = np.zeros(len(cand), dtype=bool)
        is_new[first] = True
        k = np.cumsum(is_new)
        need = kld_sample_count(k, self.kld_err, self.kld_z, self.min_particles, self.max_particles)
        enough = np.nonzero(np.arange(1, len(cand) + 1) >= need)[0]
        return int(enough[0] + 1) if len(enough) else len(cand)

    def estimate(self):
        """Mean pose and 3x3 covariance of the heaviest particle cluster (as amcl reports it),
        so that particles injected for recovery do not drag the estimate across the map; but
        the cluster the last estimate was in stays the estimate until another weighs
        switch_ratio times as much (estimated_cluster)."""
        members = estimated_cluster(self.particles[:, :2], self.weights, self.bin_size[0],
                                    self.last_xy, self.switch_ratio)
        p, w = self.particles[members], self.weights[members]
        w = w / w.sum() if w.sum() > 0 else np.full(len(w), 1.0 / len(w))
        x, y = np.dot(w, p[:, 0]), np.dot(w, p[:, 1])
        th = math.atan2(np.dot(w, np.sin(p[:, 2])), np.dot(w, np.cos(p[:, 2])))
        d = p - np.array([x, y, th])
        d[:, 2] = wrap_angle(d[:, 2])
        cov = (d * w[:, None]).T @ d
        self.last_xy = (float(x), float(y))
        return (float(x), float(y), float(th)), cov


def estimated_cluster(xy, weights, cell, last_xy=None, switch_ratio=1.0):
    """Mask of the particles of the cluster (8-connected group of occupied cells) the estimate
    is made from: the heaviest, unless the cluster nearest to the last estimate (last_xy) still
    weighs at least 1 / switch_ratio of it.

    Why not simply the heaviest, as amcl does: where a map repeats itself (the small loop's
    corners), a scan fits two places about equally and the heaviest cluster can change with a
    few percent of weight. In one CI run the estimate jumped 2.2 m with 0.02 m of odometry, the
    cloud split 1262 / 1176 particles between two corridors whose weights differed by 3 %; the
    EKF took the jump and navigation stood still against a wall it believed it was in. A
    cluster that is really the better one soon weighs several times the other."""
    ij = np.floor(xy / cell).astype(np.int64)
    origin = ij.min(axis=0)
    ij -= origin
    shape = tuple(ij.max(axis=0) + 1)
    occupied = np.zeros(shape, dtype=bool)
    occupied[ij[:, 0], ij[:, 1]] = True
    labels, n = ndimage.label(occupied, structure=np.ones((3, 3)))
    if n <= 1:
        return np.ones(len(xy), dtype=bool)
    lab = labels[ij[:, 0], ij[:, 1]]
    weight = np.bincount(lab, weights=weights, minlength=n + 1)
    best = int(np.argmax(weight))
    if last_xy is not None:
        dist = np.hypot(xy[:, 0] - last_xy[0], xy[:, 1] - last_xy[1])
        nearest = int(np.argmin(dist))
        kept = int(lab[nearest])
        # a cluster that has died out near the last estimate keeps nothing
        if dist[nearest] <= 2 * cell and weight[kept] * switch_ratio >= weight[best]:
            best = kept
    return lab == best
