#!/usr/bin/python3
"""Benchmark (prints, asserts nothing): per-call cost of the navigation demo's algorithms on
the office floor, side by side in one run: ray casting per scan, AMCL update vs particle
count, EKF cycle, Dijkstra plan, DWA cycle, marker rendering and detection.

    /usr/bin/python3 tests/bench/bench_nav_algorithms.py
"""
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "src", "anyscale_nav_demo", "src"))

import anyscale_nav_demo  # noqa: E402,F401  (caps BLAS threads)
import numpy as np  # noqa: E402

from anyscale_nav_demo import ar_markers, costmap, laser_model, raycast  # noqa: E402
from anyscale_nav_demo.dwa import DWAConfig, choose_velocity  # noqa: E402
from anyscale_nav_demo.ekf import PlanarEKF  # noqa: E402
from anyscale_nav_demo.occupancy_map import load_map  # noqa: E402
from anyscale_nav_demo.particle_filter import LikelihoodField, ParticleFilter  # noqa: E402

MAP = os.path.join(HERE, "..", "..", "src", "anyscale_nav_demo", "maps", "office_floor.yaml")


def per_call_ms(fn, repeat):
    fn()
    t = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - t) / repeat * 1000.0


def main():
    m = load_map(MAP)
    rng = np.random.default_rng(0)
    pose = (20.0, 5.9, 0.1)
    angles = raycast.beam_angles(laser_model.URG_ANGLE_MIN, laser_model.URG_ANGLE_MAX,
                                 laser_model.URG_BEAMS)

    def cast():
        return raycast.cast_rays(m.occupied, m.resolution, m.origin[:2], pose[0], pose[1],
                                 pose[2] + angles, laser_model.URG_RANGE_MAX)

    ray_ms = per_call_ms(cast, 50)
    print("ray cast, 682 beams to 5.6 m:         %7.2f ms per scan  (%4.1f %% of a core at 10 Hz)"
          % (ray_ms, ray_ms * 10 / 10.0))

    scan = cast()
    field = LikelihoodField(m)
    step = int(math.ceil(len(scan) / 60.0))
    sub_r, sub_a = scan[::step], angles[::step]
    print("\nAMCL cycle (predict + likelihood update + estimate + KLD resample), 60 beams:")
    print("  particles   ms/update   %core@2Hz   %core@5Hz   ratio to 500")
    base = None
    for n in (100, 500, 1000, 2000, 5000):
        pf = ParticleFilter(field, rng, min_particles=n, max_particles=n)
        pf.init_gaussian(pose, 0.01, 0.01, 0.005)

        def cycle():
            pf.predict((0, 0, 0), (0.08, 0, 0.01))
            pf.update(sub_r, sub_a, (0.2, 0.0, 0.0))
            pf.estimate()
            pf.resample()
        ms = per_call_ms(cycle, 20)
        base = ms if n == 500 else base
        print("  %9d   %9.2f   %9.1f   %9.1f   %s" % (n, ms, ms * 2 / 10, ms * 5 / 10,
                                                      "%.2f" % (ms / base) if base else "-"))

    f = PlanarEKF(pose)
    ekf_ms = per_call_ms(lambda: (f.predict(0.1), f.update_twist(0.4, 0.0, 0.01, 0.01),
                                  f.update_pose(pose, np.eye(3) * 0.01)), 200)
    print("\nEKF predict + twist + pose update:     %7.3f ms" % ekf_ms)

    cost = costmap.inflate(m.occupied, m.data < 0, m.resolution, 0.3, 0.9, 3.0)
    coarse = costmap.downsample_max(cost, 2)
    t = time.perf_counter()
    graph = costmap.grid_graph(coarse, 0.1, 3.0)
    graph_ms = (time.perf_counter() - t) * 1000
    goal = (34.65, 20.275)
    nf_ms = per_call_ms(lambda: costmap.NavigationFunction(coarse, 0.1, (0, 0), graph, goal), 5)
    nf = costmap.NavigationFunction(coarse, 0.1, (0, 0), graph, goal)
    path_ms = per_call_ms(lambda: nf.path_from(pose[:2]), 20)
    print("planner graph build (once per map):    %7.1f ms, %d nodes" % (graph_ms, graph.shape[0]))
    print("Dijkstra from a goal (once per goal):  %7.1f ms" % nf_ms)
    print("path extraction (every control cycle): %7.2f ms" % path_ms)
    path = nf.path_from(pose[:2])
    hit = np.isfinite(scan)
    pts = np.column_stack([pose[0] + scan[hit] * np.cos(angles[hit]),
                           pose[1] + scan[hit] * np.sin(angles[hit])])[::2]
    cfg = DWAConfig()
    dwa_ms = per_call_ms(lambda: choose_velocity(pose, (0.3, 0.0), path,
                                                 (cost, m.resolution, (0, 0)), pts, cfg), 50)
    print("DWA, %d x %d samples, %d laser points:  %7.2f ms  (%4.1f %% of a core at 10 Hz)"
          % (cfg.vx_samples, cfg.vth_samples, len(pts), dwa_ms, dwa_ms))

    cam = ar_markers.PinholeCamera()
    bg = ar_markers.background(cam)
    tex = {0: ar_markers.marker_texture(0)}
    mk = [{"id": 0, "x": 21.0, "y": 4.9, "z": 0.4, "yaw": math.pi / 2, "size": 0.4}]
    cam_pose = (20.9, 5.7, 0.4, -math.pi / 2)
    render_ms = per_call_ms(lambda: ar_markers.render(cam, bg, cam_pose, mk, tex), 200)
    img, _ = ar_markers.render(cam, bg, cam_pose, mk, tex)
    det = ar_markers.MarkerDetector(cam.K, cam.D, 0.4)
    det_ms = per_call_ms(lambda: det.detect(img), 200)
    empty_ms = per_call_ms(lambda: det.detect(bg), 200)
    print("marker render (one in view):           %7.2f ms" % render_ms)
    print("ArUco detect + pose, marker / empty:   %7.2f / %.2f ms  (%4.1f %% of a core at 30 Hz)"
          % (det_ms, empty_ms, det_ms * 3))


if __name__ == "__main__":
    main()
