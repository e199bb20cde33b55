"""The CPU calibration bench's report (tests/bench/bench_cpu_calibration.py), pure: the node sets
and Table I's topics it measures, and its tables of one case's steps: each topic's rate beside
Table I's freq_min/freq_opt with the host-speed workload's median, each node's and each group's
CPU with the groups' throttling, and in the robot case AMCL's, AR's and navigation's share of
the robot group beside Table II; the report that ends a run."""
import statistics
import time

ROBOT_NODES = ["laser", "odometer", "camera", "base_driver", "user", "map_server", "odometry",
               "ekf", "navigation", "amcl", "ar_recognition"]
LAPTOP_NODES = ["amcl", "ar_recognition"]
SIM = "world_sim"
# topic -> (Table I freq_min, freq_opt)
TOPICS = {"/amcl_pose": (2, 5), "/ar_markers": (1, 30), "/scan": (5, 10), "/joint_states": (10, 40),
          "/odom": (5, 10), "/odometry/filtered": (2, 5), "/camera/image_raw": (1, 30)}


def qname(q):
    return "none" if q <= 0 else "%.2f" % q


def quota_cells(result):
    """The robot's and the laptop's quota, as the tables' first two columns."""
    laptop = "-" if result["laptop_q"] is None else qname(result["laptop_q"])
    return "%-7s %-7s" % (qname(result["robot_q"]), laptop)


def host_ms(result):
    value = result.get("host_ms")
    return float("nan") if value is None else value


def step_line(r):
    """One step's result in a line, as the bench logs it when the step ends."""
    return ("  /amcl_pose %.2f Hz, /ar_markers %.2f Hz, amcl %.1f %%, ar %.1f %% of a core, "
            "host workload %.1f ms"
            % (r["rates"]["/amcl_pose"], r["rates"]["/ar_markers"],
               r["cpu"].get("amcl", float("nan")),
               r["cpu"].get("ar_recognition", float("nan")), host_ms(r)))


def print_report(args, cores, total_s, reference_cpu_ms, results_r, results_l):
    """The report at the end of a run: its settings, the host's speed over the steps, and the
    table of each case measured (results_r: the robot case, results_l: the laptop case)."""
    print("\nCPU calibration, %s, %d cores, world %s, %.0f s per step, %.0f s total"
          % (time.strftime("%Y-%m-%d %H:%M"), cores, args.world, args.duration, total_s))
    print("amcl: %s\nar_recognition: %s" % (args.amcl_params, args.ar_params))
    samples = [ms for r in results_r + results_l for ms in r.get("host_samples", [])]
    if samples:
        print("host-speed workload (anyscale_testbed/host_speed.py): median %.1f ms of CPU over "
              "the steps (%.1f-%.1f, %d measurements); the calibration file's reference_cpu_ms "
              "is %s: state the median there if these quotas are chosen"
              % (statistics.median(samples), min(samples), max(samples), len(samples),
                 reference_cpu_ms))
    if results_r:
        print_table("ROBOT case: the robot's whole node set in one group (simulator outside)",
                    results_r, ROBOT_NODES, laptop=False)
    if results_l:
        print_table("LAPTOP case: AMCL + AR alone in the laptop group, the rest in the robot group",
                    results_l, ROBOT_NODES, laptop=True)


def print_table(title, results, nodes, laptop):
    print("\n" + title)
    cols = ["/amcl_pose", "/ar_markers", "/scan", "/joint_states", "/odom", "/odometry/filtered",
            "/camera/image_raw"]
    head = "%-7s %-7s" % ("robot", "laptop") + "".join("%9s" % c.split("/")[-1][:8] for c in cols)
    minimum_optimum = ", ".join("%s %d/%d" % (c.split("/")[-1], *TOPICS[c]) for c in cols)
    print("rates (Hz; Table I min/opt: " + minimum_optimum + "); host_ms: the host-speed "
          "workload's median CPU ms while they were counted")
    print(head + "%9s" % "host_ms")
    for r in results:
        print(quota_cells(r)
              + "".join("%9.2f" % r["rates"].get(c, float("nan")) for c in cols)
              + "%9.1f" % host_ms(r))
    print("CPU (% of one core; group = sum of its nodes; throttled = % of CFS periods)")
    names = nodes + [SIM]
    print("%-7s %-7s" % ("robot", "laptop") + "".join("%9s" % n[:8] for n in names)
          + "%9s%9s%9s" % ("robot_g", "laptop_g", "thr_r/l"))
    for r in results:
        c = r["cpu"]
        lap_set = set(LAPTOP_NODES) if laptop else set()
        rg = sum(v for n, v in c.items() if n in ROBOT_NODES and n not in lap_set and v == v)
        lg = sum(v for n, v in c.items() if n in lap_set and v == v)
        th = []
        for key in ("robot", "laptop"):
            t = [v for k, v in r["throttle"].items() if k.endswith(key)]
            th.append("%d" % (100.0 * t[0][1] / t[0][0]) if t and t[0][0] else "-")
        print(quota_cells(r)
              + "".join("%9.1f" % c.get(n, float("nan")) for n in names)
              + "%9.1f%9s%9s" % (rg, "%.1f" % lg if laptop else "-", "/".join(th)))
    if not laptop:
        print("share of the robot group (AMCL / AR / navigation, cf. Table II: 50 / 33 / 20 %):")
        for r in results:
            c = r["cpu"]
            rg = sum(v for n, v in c.items() if n in ROBOT_NODES and v == v) or float("nan")
            print("  robot %-5s  amcl %4.0f %%  ar %4.0f %%  navigation %4.0f %%"
                  % (qname(r["robot_q"]), 100 * c.get("amcl", 0) / rg,
                     100 * c.get("ar_recognition", 0) / rg, 100 * c.get("navigation", 0) / rg))
