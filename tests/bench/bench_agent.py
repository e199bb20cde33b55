#!/usr/bin/python3
"""Benchmark of the anyscale agent (issue 3). Prints figures measured side by side in one run;
asserts nothing (this 2-core machine is noisy: compare the ratios, not absolute numbers).

  1. agent CPU: idle; 20 supervised processes with 10 watched topics (two 30 Hz images of
     ~300 KB) at 2 Hz sampling; the same without topics; `rostopic hz` on the same topics.
  2. rate error against `rostopic hz` and against roscpp's own topic statistics
     (/enable_statistics), and CPU % error against psutil.
  3. start latency (service call -> registered with the master -> first message) of a rospy
     and a roscpp node, and stop latency.

Needs the workspace built and sourced (anyscale_agent and test_talker_cpp from
anyscale_agent_cpp). Runs its own roscore on a free port and stops everything it started.
Usage: /usr/bin/python3 tests/bench/bench_agent.py [--seconds 20] [--repeats 5]
"""
import argparse
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import xmlrpc.client

import psutil


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


PORT = free_port()
os.environ["ROS_MASTER_URI"] = "http://127.0.0.1:%d" % PORT
os.environ.setdefault("ROS_HOSTNAME", "127.0.0.1")

import rosgraph  # noqa: E402  (after ROS_MASTER_URI is set)
import rospy  # noqa: E402
import rostopic  # noqa: E402
from anyscale_msgs.msg import ScaleStatus  # noqa: E402
from anyscale_testbed.bench_runs import interrupt_then_kill  # noqa: E402
from anyscale_msgs.srv import SetWatchedTopics, StartNode, StopNode  # noqa: E402
from catkin.find_in_workspaces import find_in_workspaces  # noqa: E402

IMAGE_TOPICS = ["/bench/image1", "/bench/image2"]
SMALL_RATES = {"/bench/t10": 10, "/bench/t20": 20, "/bench/t40": 40, "/bench/t100": 100,
               "/bench/t5": 5, "/bench/t15": 15, "/bench/t30": 30, "/bench/t50": 50}
WATCHED = IMAGE_TOPICS + sorted(SMALL_RATES)


def model_yaml():
    nodes = []
    for i, topic in enumerate(IMAGE_TOPICS):
        nodes.append(("camera%d" % (i + 1), "test_talker_cpp",
                      {"rate": 30.0, "topic": topic, "payload_bytes": 300000}))
    for topic, rate in sorted(SMALL_RATES.items()):
        nodes.append(("pub_" + topic.split("/")[-1], "test_talker_cpp",
                      {"rate": float(rate), "topic": topic}))
    for i in range(10):
        nodes.append(("idle%d" % i, "test_talker_cpp", {"rate": 1.0, "topic": "/bench/idle%d" % i}))
    nodes.append(("talker_py", "talker.py", {"rate": 20.0, "topic": "/bench/py_out"}))
    nodes.append(("talker_cpp", "test_talker_cpp", {"rate": 20.0, "topic": "/bench/cpp_out"}))
    nodes.append(("burner", "burner.py", {"fraction": 0.5}))
    lines = ["nodes:"]
    for name, exe, params in nodes:
        p = ", ".join("%s: %s" % (k, v) for k, v in params.items())
        lines.append("  - {name: %s, launch: {package: anyscale_agent_cpp, type: %s, "
                     "params: {%s}}}" % (name, exe, p))
    return "\n".join(lines) + "\n"


class Bench:
    def __init__(self, args):
        self.args = args
        self.procs = []
        self.tmp = tempfile.mkdtemp(prefix="bench_agent_")
        self.model = os.path.join(self.tmp, "model.yaml")
        with open(self.model, "w") as f:
            f.write(model_yaml())
        found = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                                   first_matching_workspace_only=True)
        if not found:
            sys.exit("anyscale_agent not built: build the workspace and source devel/setup.bash")
        self.agent_bin = found[0]
        self.statuses = []

    def spawn(self, argv, **kw):
        p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, **kw)
        self.procs.append(p)
        return p

    def close(self):
        for p in reversed(self.procs):
            if p.poll() is None:
                interrupt_then_kill(p, 20)
        shutil.rmtree(self.tmp, ignore_errors=True)

    def start_agent(self):
        env = dict(os.environ, ROS_HOME=self.tmp)
        self.agent = self.spawn([self.agent_bin, "__name:=anyscale_agent_bench", "_scale:=bench",
                                 "_is_master:=true", "_model:=" + self.model, "_watch_all:=true",
                                 "_sample_rate_hz:=2.0", "_sigint_timeout_s:=5.0"], env=env)
        ns = "/anyscale/bench/"
        rospy.wait_for_service(ns + "start_node", 20)
        self.start = rospy.ServiceProxy(ns + "start_node", StartNode, persistent=False)
        self.stop = rospy.ServiceProxy(ns + "stop_node", StopNode)
        self.watch = rospy.ServiceProxy(ns + "set_watched_topics", SetWatchedTopics)
        rospy.Subscriber("/anyscale/status", ScaleStatus, self.statuses.append, queue_size=100)

    @staticmethod
    def cpu_of(pids, seconds):
        """% of one core used by `pids` over `seconds` (utime+stime, as top)."""
        procs = [psutil.Process(p) for p in pids]
        t0 = time.monotonic()
        c0 = [sum(p.cpu_times()[:2]) for p in procs]
        time.sleep(seconds)
        t1 = time.monotonic()
        c1 = [sum(p.cpu_times()[:2]) for p in procs]
        return [100.0 * (b - a) / (t1 - t0) for a, b in zip(c0, c1)]

    def run(self):
        self.spawn(["roscore", "-p", str(PORT)], env=dict(os.environ, ROS_HOME=self.tmp))
        deadline = time.monotonic() + 30
        while not rosgraph.is_master_online():
            if time.monotonic() > deadline:
                sys.exit("roscore did not come up")
            time.sleep(0.2)
        rospy.init_node("bench_agent", disable_signals=True)
        self.start_agent()
        secs = self.args.seconds
        print("== 1. agent CPU (%% of one core, utime+stime over %.0f s; goal <= 1 %%, "
              "K3s agent idles ~3 %%)" % secs)
        idle = self.cpu_of([self.agent.pid], secs)[0]
        print("  agent, no nodes, no topics              : %6.2f %%" % idle)
        names = (["camera1", "camera2"] + ["pub_" + t.split("/")[-1] for t in sorted(SMALL_RATES)]
                 + ["idle%d" % i for i in range(10)])
        for n in names:
            r = self.start(node=n, param_overrides=[], lease_s=0.0)
            assert r.success, r.message
        time.sleep(5.0)
        self.watch(topics=[])
        loaded_no_topics = self.cpu_of([self.agent.pid], secs)[0]
        print("  agent, 20 processes, 0 watched topics   : %6.2f %%" % loaded_no_topics)
        self.watch(topics=sorted(SMALL_RATES))
        time.sleep(3.0)
        small = self.cpu_of([self.agent.pid], secs)[0]
        print("  agent, 20 processes, 8 small topics     : %6.2f %%  (%d msg/s, no images)"
              % (small, sum(SMALL_RATES.values())))
        self.watch(topics=WATCHED)
        time.sleep(3.0)
        full = self.cpu_of([self.agent.pid], secs)[0]
        print("  agent, 20 processes, 10 watched topics  : %6.2f %%  "
              "(+ 2 x 30 Hz x 300 KB images = 18 MB/s)" % full)
        hz = self.spawn(["rostopic", "hz", "-w", "1000"] + WATCHED)
        time.sleep(3.0)
        both = self.cpu_of([self.agent.pid, hz.pid], secs)
        print("  same, measured while rostopic hz runs   : %6.2f %%  vs rostopic hz on the same "
              "topics: %.2f %% (ratio %.3f)"
              % (both[0], both[1], both[0] / both[1] if both[1] else float("nan")))
        hz.send_signal(2)
        hz.wait()

        print("== 2a. rate error against rostopic hz (same interval, %.0f s)" % secs)
        self.rate_errors()
        print("== 2b. roscpp's own topic statistics (/enable_statistics) on the agent's "
              "subscriptions")
        self.roscpp_statistics(secs)
        print("== 2c. CPU %% error against psutil (node 'burner', %.0f s)" % secs)
        self.cpu_error(secs)
        for n in names:
            self.stop(node=n, wait=False)
        time.sleep(3.0)
        print("== 3. start / stop latency (%d runs each; median [min, max] in ms)"
              % self.args.repeats)
        self.latency("talker_py", "/bench/py_out", "rospy")
        self.latency("talker_cpp", "/bench/cpp_out", "roscpp")

    def mean_rates(self, samples):
        out = {}
        for t in WATCHED:
            vals = [s.rate_hz for st in samples for s in st.topics if s.topic == t]
            out[t] = sum(vals) / len(vals) if vals else float("nan")
        return out

    def rate_errors(self):
        hz = rostopic.ROSTopicHz(-1)
        subs = [rospy.Subscriber(t, rospy.AnyMsg, hz.callback_hz, callback_args=t) for t in WATCHED]
        time.sleep(2.0)
        with hz.lock:
            for t in WATCHED:
                hz.set_msg_t0(-1, topic=t)
        first = len(self.statuses)
        time.sleep(self.args.seconds)
        mine = self.mean_rates(self.statuses[first:])
        errors = []
        for t in WATCHED:
            ref = hz.get_hz(t)
            ref = ref[0] if ref else float("nan")
            err = 100.0 * (mine[t] - ref) / ref
            errors.append(abs(err))
            print("  %-16s agent %8.3f Hz   rostopic hz %8.3f Hz   error %+6.2f %%"
                  % (t, mine[t], ref, err))
        print("  max |error| %.2f %% (goal <= 1 %%)" % max(errors))
        for s in subs:
            s.unregister()

    def roscpp_statistics(self, secs):
        from rosgraph_msgs.msg import TopicStatistics
        # roscpp reads /enable_statistics when a subscription is made: re-subscribe the counters.
        rospy.set_param("/enable_statistics", True)
        self.watch(topics=[])
        time.sleep(1.0)
        self.watch(topics=WATCHED)
        stats = {}
        sub = rospy.Subscriber("/statistics", TopicStatistics,
                               lambda m: stats.setdefault(m.topic, []).append(m), queue_size=200)
        time.sleep(3.0)
        first = len(self.statuses)
        with_stats = self.cpu_of([self.agent.pid], secs)[0]
        mine = self.mean_rates(self.statuses[first:])
        sub.unregister()
        rospy.set_param("/enable_statistics", False)
        self.watch(topics=[])
        time.sleep(1.0)
        self.watch(topics=WATCHED)
        print("  agent CPU with roscpp statistics on: %.2f %% (compare with the 10-topic row "
              "above)" % with_stats)
        for t in WATCHED:
            msgs = [m for m in stats.get(t, []) if m.node_sub == "/anyscale_agent_bench"]
            if not msgs:
                print("  %-16s no /statistics message in %.0f s" % (t, secs))
                continue
            period = statistics.mean(m.period_mean.to_sec() for m in msgs)
            ref = 1.0 / period if period > 0 else float("nan")
            print("  %-16s agent %8.3f Hz   roscpp statistics 1/period_mean %8.3f Hz   (%d windows)"
                  % (t, mine[t], ref, len(msgs)))

    def cpu_error(self, secs):
        r = self.start(node="burner", param_overrides=[], lease_s=0.0)
        assert r.success, r.message
        time.sleep(4.0)
        first = len(self.statuses)
        ref = self.cpu_of([r.pid], secs)[0]
        vals = [n.cpu_percent for st in self.statuses[first + 1:]
                for n in st.nodes if n.name == "/burner"]
        mine = sum(vals) / len(vals)
        print("  agent %.2f %%   psutil %.2f %%   difference %+.2f points (%+.1f %%)"
              % (mine, ref, mine - ref, 100.0 * (mine - ref) / ref))
        self.stop(node="burner", wait=True)

    @staticmethod
    def registered(node):
        try:
            uri = rosgraph.Master("/bench").lookupNode(node)
            return xmlrpc.client.ServerProxy(uri).getPid("/bench")[2]
        except Exception:  # not registered yet, or gone
            return None

    def latency(self, node, topic, kind):
        reply, reg, first_msg, stop, unreg = [], [], [], [], []
        for _ in range(self.args.repeats):
            got = []
            sub = rospy.Subscriber(topic, rospy.AnyMsg,
                                   lambda m: got.append(time.monotonic()) if not got else None)
            time.sleep(0.5)
            t0 = time.monotonic()
            r = self.start(node=node, param_overrides=[], lease_s=0.0)
            reply.append(time.monotonic() - t0)
            assert r.success, r.message
            while self.registered("/" + node) != r.pid:
                time.sleep(0.002)
            reg.append(time.monotonic() - t0)
            while not got:
                time.sleep(0.002)
            first_msg.append(got[0] - t0)
            sub.unregister()
            t1 = time.monotonic()
            self.stop(node=node, wait=True)
            stop.append(time.monotonic() - t1)
            while self.registered("/" + node) is not None:
                time.sleep(0.002)
            unreg.append(time.monotonic() - t1)

        def fmt(v):
            return "%7.1f [%7.1f, %7.1f]" % (1e3 * statistics.median(v), 1e3 * min(v), 1e3 * max(v))

        print("  %-7s start: service reply %s  registered %s  first message %s"
              % (kind, fmt(reply), fmt(reg), fmt(first_msg)))
        print("  %-7s stop : process gone  %s  unregistered %s" % (kind, fmt(stop), fmt(unreg)))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0,
                        help="length of each measurement [s]")
    parser.add_argument("--repeats", type=int, default=5, help="start/stop runs per node kind")
    bench = Bench(parser.parse_args())
    try:
        bench.run()
    finally:
        rospy.signal_shutdown("done")
        bench.close()


if __name__ == "__main__":
    main()
