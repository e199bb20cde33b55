"""What the system tests of the stock relay (relay_model.yaml) share: the two scales launched
with a robot-side probe that logs each /chatter_relay message with its sender, and where the
relay's instances run."""
import os
import subprocess
import sys

import yaml

from anyscale_testbed.two_scale_testbed import namespace_exec

PROBE = """
import sys, time, rospy
from std_msgs.msg import String
rospy.init_node("relay_probe", anonymous=True)
out = open(sys.argv[1], "a", buffering=1)
rospy.Subscriber("/chatter_relay", String,
                 lambda m: out.write("%.3f %s\\n" % (time.time(),
                                                      m._connection_header["callerid"])))
rospy.spin()
"""


HERE = os.path.dirname(os.path.abspath(__file__))


def launch_relay_bed(bed, session, run_dir, model, receipts_path, hysteresis_s,
                     agent_respawn=False, laptop_args=()):
    """The robot (agent, decision node, a clean 27 Mbit/s link, monitor), the laptop's agent,
    and the probe writing every /chatter_relay receipt to receipts_path. agent_respawn: the
    robot's agent is started again when it ends, and adopts the nodes it left; laptop_args:
    more args of the laptop's agent.launch."""
    session.roslaunch("robot", "robot", [
        os.path.join(HERE, "relay_robot.launch"), f"model:={model}", "schedule:=[[0, 27]]",
        f"record_path:={os.path.join(run_dir, 'record.json')}", "duration_s:=120",
        f"hysteresis_s:={hysteresis_s}", f"uplink_interface:={bed.uplink_interface('robot')}",
        f"agent_respawn:={str(agent_respawn).lower()}"],
        wait_for_master=False)
    session.roslaunch("laptop", "laptop", [
        "anyscale_agent_cpp", "agent.launch", "scale:=laptop", "master_scale:=robot",
        f"model:={model}", "sample_rate_hz:=5.0", "sigint_timeout_s:=2.0", *laptop_args])
    bed.start("robot", [sys.executable, "-c", PROBE, receipts_path], session.env("robot"),
              os.path.join(run_dir, "logs", "probe.log"), cpu_quota=False)


def paused_at_home_model(run_dir):
    """relay_model.yaml with the relay declared launch.pause_at_home, written into run_dir."""
    with open(model_path()) as f:
        model = yaml.safe_load(f)
    for node in model["nodes"]:
        if node["name"] == "relay":
            node["launch"]["pause_at_home"] = True
    path = os.path.join(run_dir, "relay_paused_at_home.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(model, f)
    return path


def process_state(pid):
    """The state letter of /proc/PID/stat (T: stopped, e.g. paused), or "-" if it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "-"


def model_path():
    pkg = subprocess.run(["rospack", "find", "anyscale_core"], capture_output=True, text=True)
    return os.path.join(pkg.stdout.strip(), "test", "config", "relay_model.yaml")


def relay_processes():
    """pid -> the node name it was started under, for every live relay on this machine."""
    return processes_named("relay")


def processes_named(node):
    """pid -> the node name it was started under (`node`, or node__SCALE), for every live
    process on this machine started with such a __name."""
    found = {}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                args = f.read().decode(errors="replace").split("\0")
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    continue
        except OSError:
            continue
        for a in args:
            if a == f"__name:={node}" or a.startswith(f"__name:={node}__"):
                found[int(pid)] = a.split(":=", 1)[1]
    return found


def relay_in(namespace):
    """(pid, name) of the relay running in a network namespace (its /proc ns link), or None."""
    for pid, name in relay_processes().items():
        try:
            if os.readlink(f"/proc/{pid}/ns/net") == namespace:
                return pid, name
        except OSError:
            continue
    return None


def in_scale(bed, session, scale, argv):
    """argv run to its end inside a scale's network namespace, with that scale's ROS env."""
    return subprocess.run(namespace_exec(bed.end(scale), argv), env=session.env(scale),
                          capture_output=True, text=True, timeout=20)


def receipts(path):
    """[(wall time, callerid)] of every /chatter_relay message the robot's probe received."""
    try:
        with open(path) as f:
            return [(float(t), who) for t, who in (line.split() for line in f if line.strip())]
    except FileNotFoundError:
        return []
