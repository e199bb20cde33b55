#!/usr/bin/python3
"""rostest: nodes given bad maps or parameters exit with code 1 and a clear message."""
import os
import subprocess
import tempfile
import unittest

import rospy
import rostest
from roslib.packages import find_node

MAPS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "maps")


def run(node, *args):
    """Run a node with command-line params; a fresh name each time, as _param:= values stay
    on the parameter server under the node's name."""
    exe = find_node("anyscale_nav_demo", node)[0]
    run.count = getattr(run, "count", 0) + 1
    p = subprocess.run([exe, "__name:=bad_%s_%d" % (node, run.count)] + list(args),
                       capture_output=True, text=True, timeout=30)
    return p.returncode, p.stdout + p.stderr


class BadInput(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("bad_input")
        cls.tmp = tempfile.mkdtemp()

    def check(self, node, args, *expect):
        code, out = run(node, *args)
        self.assertEqual(code, 1, out)
        self.assertNotIn("Traceback", out)
        for e in expect:
            self.assertIn(e, out)

    def test_map_server_missing_yaml(self):
        self.check("map_server", ["_map_file:=/nonexistent/floor.yaml"], "/nonexistent/floor.yaml",
                   "not found")

    def test_map_server_malformed_yaml(self):
        path = os.path.join(self.tmp, "broken.yaml")
        with open(path, "w") as f:
            f.write("image: [unclosed\n")
        self.check("map_server", ["_map_file:=" + path], path, "malformed YAML")

    def test_map_server_bad_pgm(self):
        pgm = os.path.join(self.tmp, "bad.pgm")
        with open(pgm, "wb") as f:
            f.write(b"P5\n10 10\n255\n" + bytes(7))
        path = os.path.join(self.tmp, "badpgm.yaml")
        with open(path, "w") as f:
            f.write("image: bad.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
                    "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
        self.check("map_server", ["_map_file:=" + path], pgm, "truncated")

    def test_map_server_without_map_param(self):
        self.check("map_server", [], "map_file", "not set")

    def test_amcl_bad_particle_counts(self):
        self.check("amcl", ["_min_particles:=900", "_max_particles:=100"],
                   "min_particles", "max_particles")

    def test_amcl_negative_sigma(self):
        self.check("amcl", ["_laser_sigma_hit:=-1"], "laser_sigma_hit", "> 0")

    def test_navigation_bad_goals(self):
        self.check("navigation", ["_goals:=[1, 2]"], "goals", "[x, y, yaw, marker_id]")

    def test_world_sim_missing_world(self):
        self.check("world_sim", ["_world_file:=/nonexistent/world.yaml"], "/nonexistent/world.yaml")

    def test_base_driver_bad_rate(self):
        self.check("base_driver", ["_rate:=0"], "rate", "> 0")


if __name__ == "__main__":
    rostest.rosrun("anyscale_nav_demo", "bad_input", BadInput)
