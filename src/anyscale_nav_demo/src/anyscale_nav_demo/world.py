"""The simulated world: the floor map plus what the map does not show, and the robot's physics."""
import math
import os

import numpy as np
from scipy import ndimage

from .diff_drive import integrate_arc, wheel_arcs_to_motion
from .occupancy_map import MapError, load_map, read_yaml_mapping


class World:
    """Ground-truth occupancy (map + extra obstacles), markers and a distance field for bumping."""

    def __init__(self, world_file):
        desc = read_yaml_mapping(world_file, "world file", "a 'map' key")
        if "map" not in desc:
            raise MapError("%s: expected a mapping with a 'map' key" % world_file)
        map_path = os.path.join(os.path.dirname(world_file), str(desc["map"]))
        self.map = load_map(map_path)
        self.occupied = self.map.occupied.copy()
        for box in desc.get("extra_obstacles") or []:
            self.add_box(*box)
        self.markers = desc.get("markers") or []
        self.start = tuple(desc.get("start", (0.0, 0.0, 0.0)))
        self.goals = desc.get("goals") or []
        self.clearance = ndimage.distance_transform_edt(~self.occupied) * self.map.resolution

    def add_box(self, x0, y0, x1, y1):
        c0, r0 = self.map.world_to_cell(min(x0, x1), min(y0, y1))
        c1, r1 = self.map.world_to_cell(max(x0, x1), max(y0, y1))
        self.occupied[max(r0, 0):r1 + 1, max(c0, 0):c1 + 1] = True

    def clearance_at(self, x, y):
        col, row = self.map.world_to_cell(x, y)
        if not self.map.inside(col, row):
            return 0.0
        return float(self.clearance[row, col])


class DiffDriveBody:
    """The robot's true motion: motors with a time constant, real wheel radii, a bumper."""

    def __init__(self, pose, wheel_radius_left, wheel_radius_right, wheel_separation,
                 motor_time_constant=0.1, radius=0.3):
        self.pose = tuple(pose)
        self.r = (wheel_radius_left, wheel_radius_right)
        self.b = wheel_separation
        self.tau = motor_time_constant
        self.radius = radius
        self.wheel_speed = np.zeros(2)      # rad/s, actual
        self.wheel_angle = np.zeros(2)      # rad, true cumulative
        self.bumped = False

    def step(self, cmd, dt, clearance_at):
        """Advance dt seconds towards commanded wheel speeds; returns the true wheel rotations."""
        k = 1.0 - math.exp(-dt / self.tau) if self.tau > 0 else 1.0
        self.wheel_speed += k * (np.asarray(cmd, dtype=float) - self.wheel_speed)
        d_ang = self.wheel_speed * dt
        ds, dth = wheel_arcs_to_motion(d_ang[0] * self.r[0], d_ang[1] * self.r[1], self.b)
        new = integrate_arc(self.pose, ds, dth)
        # A bumper: moving into an obstacle stalls the wheels (turning on the spot is allowed
        # when it does not bring the body closer).
        if clearance_at(new[0], new[1]) < self.radius and \
                clearance_at(new[0], new[1]) < clearance_at(self.pose[0], self.pose[1]):
            self.bumped = True
            self.wheel_speed[:] = 0.0
            return np.zeros(2)
        self.bumped = False
        self.pose = new
        self.wheel_angle += d_ang
        return d_ang

    @property
    def twist(self):
        vl, vr = self.wheel_speed[0] * self.r[0], self.wheel_speed[1] * self.r[1]
        return (vl + vr) / 2.0, (vr - vl) / self.b
