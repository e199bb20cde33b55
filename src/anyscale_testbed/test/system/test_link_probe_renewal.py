"""System test: the agents' link probes come back after their connections died in an outage
(root: network namespaces).

roscpp retries a dropped subscriber connection, but if that retry's connect() fails at once
(ENETUNREACH while the link's carrier is down) it never tries again: the subscription keeps a
dead link to a publisher the master still lists. In an evaluation run (office floor, seed 4)
this happened to the robot agent's probe subscription after an outage with flickers, and the
laptop counted as out of reach on a 27 Mbit/s link for the rest of the run. The agents renew
such a subscription from scratch (a new one: the old released first, see LinkMonitor).

The same befell the laptop agent's rate counters: a counter reading 0 Hz on a dead connection
sent AMCL and AR home 9 s after each move out (the same run). They are renewed when silent.

The test kills TCP connections between the scales (`ss -K`) while the carrier is down, so that
roscpp's retry comes during the outage, then brings the link back: within RECOVER_S the laptop
must report its link up again, and count a topic published on the robot again. Twice: every
connection, and only the counted topic's over a shorter outage (the probes live on; before the
counters renewed themselves, only a probe renewal renewed them too).

A subscription that never carried anything is as dead: when the robot's agent comes up while the
link is down, the master's news of its echo publisher never reaches the laptop agent, which had
subscribed first. Before the silence of a subscription that never heard anything counted, the
laptop reported its link down for a whole run (the main command, office floor, seed 0: the start
had no coverage, and no node moved out though the link came back at 27 Mbit/s for 169 s)."""
import functools
import os
import socket
import subprocess
import sys
import time

import pytest

from anyscale_core.polling import wait_for
from anyscale_testbed.system_test_gate import NOT_RUN

from anyscale_testbed.testbed_session import (NamespaceBed, TestbedSession, agent_binary,
                                              layout_with_cpu)
from anyscale_testbed.two_scale_testbed import namespace_exec, run

HERE = os.path.dirname(os.path.abspath(__file__))
MODEL = os.path.join(HERE, "..", "..", "..", "anyscale_agent_cpp", "test", "config",
                     "test_model.yaml")
OUTAGE_S = 3.0
SHORT_OUTAGE_S = 1.5            # the probes' 5 s of silence before a renewal not reached
# Silence before a renewal (5 s) + the probe timer, the link timeout and a status period.
RECOVER_S = 12.0

COUNTED = "/chatter"             # published on the robot, counted by the laptop's agent

# Prints "<wall time> <link up> <COUNTED's rate>" for each of the laptop agent's statuses.
WATCH = """
import sys, time, rospy
from anyscale_msgs.msg import ScaleStatus
rospy.init_node("link_watch", anonymous=True)
out = open(sys.argv[1], "a", buffering=1)
def seen(m):
    if m.scale == "laptop":
        rate = max([t.rate_hz for t in m.topics if t.topic == sys.argv[2]] or [0.0])
        out.write("%.3f %d %.2f\\n" % (time.time(), m.link.up, rate))
rospy.Subscriber("/anyscale/status", ScaleStatus, seen)
rospy.spin()
"""


def laptop_link(path):
    """[(wall time, link up, COUNTED's rate in Hz)] from the watcher's file."""
    try:
        with open(path) as f:
            return [(float(t), up == "1", float(rate))
                    for t, up, rate in (line.split() for line in f if line.strip())]
    except FileNotFoundError:
        return []


def kill_connections(bed, scale, peer_address, local_port=None):
    """The TCP sockets of the scale's namespace to the peer (from `local_port` only, if given)
    destroyed, as an outage can end them; returns how many (`ss -K` prints each it closed)."""
    where = ["dst", peer_address] + (["sport", "=", f":{local_port}"] if local_port else [])
    done = run(namespace_exec(bed.end(scale), ["ss", "-K", "-t", "-H"] + where), check=False)
    return len([line for line in done.stdout.splitlines() if line.strip()])


def listening_ports(bed, scale, program):
    """The TCP ports that `program` (its process name) listens on in the scale's namespace."""
    done = run(namespace_exec(bed.end(scale), ["ss", "-t", "-l", "-n", "-p", "-H"]), check=False)
    return [int(line.split()[3].rsplit(":", 1)[1]) for line in done.stdout.splitlines()
            if f'"{program}"' in line]


@functools.lru_cache(maxsize=None)
def socket_destroy_works():
    """Whether `ss -K` closes a TCP connection on this machine (the kernel's
    CONFIG_INET_DIAG_DESTROY): one made for the purpose on loopback, then destroyed."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        with socket.create_connection(server.getsockname()) as client:
            peer, _ = server.accept()
            with peer:
                port = client.getsockname()[1]
                run(["ss", "-K", "-t", "-H", "sport", "=", f":{port}"], check=False)
                client.settimeout(2.0)
                try:
                    return client.recv(1) == b""
                except socket.timeout:
                    return False                # still open: nothing destroyed it
                except OSError:
                    return True                 # ECONNABORTED: destroyed


def needs_socket_destroy():
    if not socket_destroy_works():
        pytest.skip(NOT_RUN + "this kernel lacks CONFIG_INET_DIAG_DESTROY (`ss -K` closed "
                    "nothing on a connection made for the purpose)")


@pytest.fixture(scope="module", params=["every connection", "the counted topic's"])
def outage(request, tmp_path_factory):
    needs_socket_destroy()
    run_dir = str(tmp_path_factory.mktemp("renewal"))
    statuses = os.path.join(run_dir, "laptop_link.txt")
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, run_dir)
        common = [f"model:={MODEL}", "master_scale:=robot", "sample_rate_hz:=5.0",
                  "sigint_timeout_s:=2.0"]
        session.roslaunch("robot", "robot", ["anyscale_agent_cpp", "agent.launch", "scale:=robot",
                                             "is_master:=true"] + common, wait_for_master=False)
        # As agent.launch starts it, and counting COUNTED though no node of the laptop uses it.
        bed.start("laptop", [agent_binary(), "__name:=anyscale_agent_laptop", "_scale:=laptop",
                             "_master_scale:=robot", f"_model:={MODEL}", "_sample_rate_hz:=5.0",
                             "_sigint_timeout_s:=2.0", "_watch_all:=true"], session.env("laptop"),
                  os.path.join(run_dir, "logs", "laptop.log"))
        # On the laptop, so that the outage leaves the watcher's own connection alone.
        bed.start("laptop", [sys.executable, "-c", WATCH, statuses, COUNTED],
                  session.env("laptop"), os.path.join(run_dir, "logs", "watch.log"),
                  cpu_quota=False)
        assert wait_for(lambda: any(up for _, up, _ in laptop_link(statuses)), 60.0, 0.2), \
            "the laptop's link never came up"
        bed.start("robot", ["rostopic", "pub", "-r", "10", COUNTED, "std_msgs/String", "hi"],
                  session.env("robot"), os.path.join(run_dir, "logs", "talker.log"))
        watch = subprocess.run(namespace_exec(bed.end("laptop"), [
            "rosservice", "call", "--wait", "/anyscale/laptop/set_watched_topics",
            "{topics: [%s]}" % COUNTED]), env=session.env("laptop"), capture_output=True,
            text=True, timeout=30)
        assert "success: True" in watch.stdout, watch.stdout + watch.stderr
        assert wait_for(lambda: any(rate > 0 for _, _, rate in laptop_link(statuses)), 30.0, 0.2), \
            "the laptop never counted " + COUNTED
        talker_ports = listening_ports(bed, "robot", "rostopic")
        assert talker_ports, "no port of the robot's rostopic publisher found to cut"
        bed.set_link(False)
        if request.param == "every connection":
            killed = (kill_connections(bed, "robot", bed.address("laptop"))
                      + kill_connections(bed, "laptop", bed.address("robot")))
            time.sleep(OUTAGE_S)
        else:
            killed = sum(kill_connections(bed, "robot", bed.address("laptop"), port)
                         for port in talker_ports)
            time.sleep(SHORT_OUTAGE_S)
        bed.set_link(True)
        back = time.time()
        wait_for(lambda: any(up and rate > 0 for t, up, rate in laptop_link(statuses)
                             if t > back + 2.5), RECOVER_S + 8.0, 0.2)
    return {"back": back, "killed": killed, "statuses": laptop_link(statuses)}


def test_the_laptop_reports_its_link_up_soon_after_the_link_returns(outage):
    assert outage["killed"] > 0, "the outage closed no connection between the scales"
    up = [t - outage["back"] for t, ok, _ in outage["statuses"] if ok and t > outage["back"]]
    print(f"link up again {up[0]:.2f} s after it returned" if up else "link never up again")
    assert up, "the laptop never reported its link up again after the outage"
    assert up[0] <= RECOVER_S, f"link up again only {up[0]:.1f} s after it returned"


def test_the_laptop_counts_a_topic_from_the_robot_again_soon_after_the_link_returns(outage):
    assert outage["killed"] > 0, "the outage closed no connection between the scales"
    # A rate from after the return: the counter's 2 s window must have seen new messages.
    counted = [t - outage["back"] for t, _, rate in outage["statuses"]
               if rate > 0 and t > outage["back"] + 2.5]
    print(f"{COUNTED} counted again {counted[0]:.2f} s after the link returned" if counted
          else f"{COUNTED} never counted again")
    assert counted, f"the laptop never counted {COUNTED} again after the outage"
    assert counted[0] <= RECOVER_S, f"{COUNTED} counted again only {counted[0]:.1f} s after"


def test_listening_ports_finds_the_ports_of_a_rostopic_publisher(tmp_path):
    """The outage above cuts the talker's connections by the ports this finds: a name that no
    longer matched would leave them open and its tests judging an outage that cut nothing."""
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, str(tmp_path))
        env = session.env("robot")
        bed.start("robot", ["roscore", "-p", str(session.port)], env,
                  str(tmp_path / "logs" / "roscore.log"), cpu_quota=False)

        def ask_master(*argv):      # inside the robot's namespace, where the master is
            return subprocess.run(namespace_exec(bed.end("robot"), [sys.executable, "-c",
                                                                    ASK_MASTER] + list(argv)),
                                  env=env, capture_output=True, text=True, timeout=90)
        up = ask_master()
        assert up.returncode == 0, up.stdout + up.stderr
        bed.start("robot", ["rostopic", "pub", "-r", "10", COUNTED, "std_msgs/String", "hi"],
                  env, str(tmp_path / "logs" / "talker.log"))
        port = ask_master(COUNTED)
        assert port.returncode == 0, port.stdout + port.stderr
        assert int(port.stdout) in listening_ports(bed, "robot", "rostopic"), port.stdout


# Waits (60 s at most) for the master, and with a topic as argv[1] for its first publisher,
# whose XML-RPC port it prints.
ASK_MASTER = """
import sys, time, rosgraph
master = rosgraph.Master("/port_test")
for _ in range(300):
    try:
        published = master.getSystemState()[0]
    except OSError:
        published = None            # not up yet
    pubs = [n for t, n in published or [] if t == sys.argv[1]] if sys.argv[1:] else []
    if pubs:
        print(master.lookupNode(pubs[0][0]).rsplit(":", 1)[1].strip("/"))
    if pubs or (published is not None and not sys.argv[1:]):
        sys.exit(0)
    time.sleep(0.2)
sys.exit("no master" + (", or no publisher of " + sys.argv[1] if sys.argv[1:] else ""))
"""


def wait_for_log(path, text, timeout_s):
    def logged():
        try:
            with open(path, errors="replace") as f:
                return text in f.read()
        except FileNotFoundError:
            return False
    assert wait_for(logged, timeout_s, 0.2), f"{path} never said {text!r}"


@pytest.fixture(scope="module")
def echo_publisher_came_during_an_outage(tmp_path_factory):
    """The laptop agent subscribed to the echoes before the robot's agent existed; the robot's
    agent advertised them with the link down; the link then came back."""
    run_dir = str(tmp_path_factory.mktemp("late_echo"))
    logs = os.path.join(run_dir, "logs")
    statuses = os.path.join(run_dir, "laptop_link.txt")
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, run_dir)
        bed.start("robot", ["roscore", "-p", str(session.port)], session.env("robot"),
                  os.path.join(logs, "roscore.log"), cpu_quota=False)
        bed.start("laptop", [agent_binary(), "__name:=anyscale_agent_laptop", "_scale:=laptop",
                             "_master_scale:=robot", f"_model:={MODEL}",
                             "_sigint_timeout_s:=2.0"], session.env("laptop"),
                  os.path.join(logs, "laptop.log"))
        bed.start("laptop", [sys.executable, "-c", WATCH, statuses, COUNTED],
                  session.env("laptop"), os.path.join(logs, "watch.log"), cpu_quota=False)
        wait_for_log(os.path.join(logs, "laptop.log"), "anyscale agent of scale 'laptop'", 60.0)
        assert wait_for(lambda: laptop_link(statuses), 30.0, 0.2), "no status from the laptop"
        bed.set_link(False)
        bed.start("robot", [agent_binary(), "__name:=anyscale_agent_robot", "_scale:=robot",
                            "_is_master:=true", f"_model:={MODEL}", "_sigint_timeout_s:=2.0"],
                  session.env("robot"), os.path.join(logs, "robot.log"))
        wait_for_log(os.path.join(logs, "robot.log"), "anyscale agent of scale 'robot'", 30.0)
        time.sleep(OUTAGE_S)     # the master's publisherUpdate to the laptop has failed by now
        bed.set_link(True)
        back = time.time()
        wait_for(lambda: any(up for t, up, _ in laptop_link(statuses) if t > back),
                 RECOVER_S + 8.0, 0.2)
    return {"back": back, "statuses": laptop_link(statuses)}


def test_a_laptop_that_never_heard_an_echo_reports_its_link_up_once_the_link_returns(
        echo_publisher_came_during_an_outage):
    outage = echo_publisher_came_during_an_outage
    up = [t - outage["back"] for t, ok, _ in outage["statuses"] if ok and t > outage["back"]]
    print(f"link up {up[0]:.2f} s after it returned" if up else "link never up")
    assert up, "the laptop never reported its link up: its echo subscription never connected"
    assert up[0] <= RECOVER_S, f"link up only {up[0]:.1f} s after it returned"
