"""The simulated world: world files, extra obstacles, the robot body's motion and bumper."""
import math
import os

import numpy as np
import pytest

from anyscale_nav_demo.occupancy_map import MapError
from anyscale_nav_demo.world import DiffDriveBody, World

MAPS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "maps")


def test_office_world_loads_with_its_obstacle():
    w = World(os.path.join(MAPS, "office_floor_world.yaml"))
    assert len(w.markers) == 4 and len(w.goals) == 5
    c, r = w.map.world_to_cell(15.1, 5.1)      # the box of maps/office_floor_world.yaml
    assert w.occupied[r, c] and not w.map.occupied[r, c]      # in the world, not on the map
    assert w.clearance_at(*w.start[:2]) == pytest.approx(1.0, abs=0.06)


def test_bad_world_files(tmp_path):
    with pytest.raises(MapError, match="world file not found"):
        World(str(tmp_path / "none.yaml"))
    (tmp_path / "w.yaml").write_text("markers: []\n")
    with pytest.raises(MapError, match="'map' key"):
        World(str(tmp_path / "w.yaml"))
    (tmp_path / "w.yaml").write_text("map: missing.yaml\n")
    with pytest.raises(MapError, match="missing.yaml"):
        World(str(tmp_path / "w.yaml"))


def test_body_follows_wheels_and_stops_at_walls():
    wall_x = 2.0
    clearance = lambda x, y: wall_x - x  # noqa: E731  (a wall at x = 2 m)
    body = DiffDriveBody((0.0, 0.0, 0.0), 0.05, 0.05, 0.32, motor_time_constant=0.0, radius=0.3)
    for _ in range(100):                  # 1 s at 8 rad/s * 0.05 m = 0.4 m/s
        body.step([8.0, 8.0], 0.01, clearance)
    assert body.pose[0] == pytest.approx(0.4, abs=1e-6) and not body.bumped
    for _ in range(1000):
        body.step([8.0, 8.0], 0.01, clearance)
    assert body.bumped and wall_x - body.pose[0] >= 0.3 - 0.005
    body.step([-8.0, 8.0], 0.01, clearance)   # turning on the spot is still allowed
    assert not body.bumped and body.pose[2] > 0


def test_unequal_wheels_drift():
    """Real wheels 0.4 % apart curve a 'straight' drive: a drift the odometry must correct for."""
    body = DiffDriveBody((0.0, 0.0, 0.0), 0.05 * 1.004, 0.05 * 0.997, 0.32, motor_time_constant=0.0)
    for _ in range(2000):
        body.step([8.0, 8.0], 0.01, lambda x, y: 10.0)
    assert abs(body.pose[1]) > 0.5 and abs(body.pose[2]) > math.radians(10)
    assert np.all(np.isfinite(body.wheel_angle))
