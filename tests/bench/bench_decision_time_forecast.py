#!/usr/bin/python3
"""Benchmark: the decision node's time per period with the link forecast and without, side by
side, at the paper's size (N=18 M=9 K=5, the Fig. 7 study's generator) and on the test bed's
model: one engine tick (paper allocator) on made-up agent reports, and with the forecast also
what the decision node adds each period: a link observation per remote scale into the map, the
robot placed on a 100 m planned path and the link ahead walked over a map of every remote
scale (1 m cells, 30 observations each, a hole every 25 m). Times are this thread's CPU time
(time.thread_time), so that other work on the shared machine does not count. Prints figures;
asserts nothing. Goal (issue 36): <= 5 ms per period with the forecast at the paper's size."""
import argparse
import os
import sys
import time

import numpy as np

SRC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src")
sys.path[:0] = [os.path.join(SRC, pkg, "src") for pkg in ("anyscale_core", "anyscale_study")]
from anyscale_core.allocators import make_allocator                # noqa: E402
from anyscale_core.characterisation import characterise            # noqa: E402
from anyscale_core.decision_engine import DecisionEngine           # noqa: E402
from anyscale_core.decision_types import DecisionParams, ScaleReport  # noqa: E402
from anyscale_core.link_forecast import PathTracker, PoseTrack, forecast_links  # noqa: E402
from anyscale_core.link_map import LinkMap                         # noqa: E402
from anyscale_core.model_loader import load_model                  # noqa: E402
from anyscale_study.simulated_systems import generate_model        # noqa: E402

TESTBED = os.path.join(SRC, "anyscale_nav_demo", "config", "testbed.yaml")
PATH_M, HOLE_EVERY_M, HOLE_M = 100.0, 25.0, 4.0
SPEED_MPS, PERIOD_S = 0.4, 0.25


def reports(ch, t):
    rates = {c.topic: c.freq_opt for c in ch.model.connections}
    quiet = {c.topic: 0.01 for c in ch.model.connections}
    master = ch.scale_names[ch.master]
    return {s: ScaleReport(s, t, 30.0, 2.0, {}, rates, True,
                           float("nan") if s == master else 20.0, topic_silence=quiet)
            for s in ch.scale_names}


def link_map_of(remote):
    m = LinkMap()
    for scale in remote:
        for x in range(int(PATH_M)):
            lost = x % HOLE_EVERY_M >= HOLE_EVERY_M - HOLE_M
            for k in range(30):
                m.add(scale, 1.8e9 + k, x + 0.5, 0.5, float("nan") if lost else 20.0, lost)
    return m


def period_times(ch, periods, forecast):
    """ms of each period after the first: tick alone, or observations, forecast and tick."""
    engine = DecisionEngine(ch, make_allocator("paper"), DecisionParams(bandwidth_hold_s=5.0))
    engine.adopt_or_start(reports(ch, 0.0), 0.0)
    remote = [s for i, s in enumerate(ch.scale_names) if i != ch.master]
    link_map, path, poses = link_map_of(remote), PathTracker(), PoseTrack()
    path.set_path([(x, 0.5) for x in np.arange(0.0, PATH_M, 0.2)])
    times = []
    for k in range(1, periods + 1):
        t = k * PERIOD_S
        x = (SPEED_MPS * t) % (PATH_M - 10.0)
        rep = reports(ch, t)
        started = time.thread_time()
        if forecast:
            poses.add(t, x, 0.5)
            for scale in remote:
                link_map.add(scale, 1.8e9 + t, x, 0.5, 20.0, False)
            engine.set_link_forecast(forecast_links(link_map, remote, path, x, 0.5,
                                                    poses.cruise_speed(), 20.0))
        engine.tick(rep, t)
        times.append(1000 * (time.thread_time() - started))
    return times[1:]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--systems", type=int, default=5, help="seeded systems (default 5)")
    p.add_argument("--periods", type=int, default=400,
                   help="decision periods per system (default 400: 100 s of driving)")
    args = p.parse_args(argv)
    systems = [("test bed (11 nodes, 2 scales)", [characterise(load_model(TESTBED))])]
    systems.append(("N=18 M=9 K=5 (the paper's size)", [
        characterise(generate_model(18, 9, 5, np.random.default_rng([1, j])))
        for j in range(args.systems)]))
    print(f"Decision time per period (CPU ms, paper allocator, {args.periods} periods of "
          f"{PERIOD_S:g} s per system, robot at {SPEED_MPS:g} m/s on a {PATH_M:g} m path)")
    print(f"{'system':<34}{'without: median':>16}{'p95':>8}{'with: median':>14}{'p95':>8}"
          f"{'ratio of medians':>18}")
    for label, chs in systems:
        without = np.concatenate([period_times(ch, args.periods, False) for ch in chs])
        with_fc = np.concatenate([period_times(ch, args.periods, True) for ch in chs])
        print(f"{label:<34}{np.median(without):>16.2f}{np.percentile(without, 95):>8.2f}"
              f"{np.median(with_fc):>14.2f}{np.percentile(with_fc, 95):>8.2f}"
              f"{np.median(with_fc) / np.median(without):>18.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
