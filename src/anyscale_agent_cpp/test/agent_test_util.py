"""Helpers shared by the agent's rostests: master lookups, waiting, service proxies."""
import time
import xmlrpc.client

import rosgraph
import rospy
from anyscale_msgs.msg import ScaleStatus
from anyscale_msgs.srv import ListNodes, RenewLeases, SetWatchedTopics, StartNode, StopNode


def registered_pid(node):
    """pid of the process the master lists under `node`, None if not registered or dead."""
    master = rosgraph.Master("/agent_test")
    try:
        uri = master.lookupNode(node)
    except (rosgraph.MasterError, OSError):
        return None
    try:
        code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/agent_test")
    except OSError:
        return None
    return pid if code == 1 else None


def wait_for(predicate, timeout, period=0.05):
    """The first truthy value of predicate() within timeout s, else the last one. (The agent's
    tests cannot use anyscale_core.polling: anyscale_core test-depends on this package.)"""
    deadline = time.monotonic() + timeout
    while not (value := predicate()) and time.monotonic() < deadline:
        time.sleep(period)
    return value


class Agent:
    """Service proxies and the latest status of the agent of one scale."""

    def __init__(self, scale, timeout=20.0):
        self.scale = scale
        ns = "/anyscale/%s/" % scale
        for name in ("start_node", "stop_node", "renew_leases", "list_nodes", "set_watched_topics"):
            rospy.wait_for_service(ns + name, timeout)
        self.start = rospy.ServiceProxy(ns + "start_node", StartNode)
        self.stop = rospy.ServiceProxy(ns + "stop_node", StopNode)
        self.renew = rospy.ServiceProxy(ns + "renew_leases", RenewLeases)
        self.list = rospy.ServiceProxy(ns + "list_nodes", ListNodes)
        self.set_watched = rospy.ServiceProxy(ns + "set_watched_topics", SetWatchedTopics)
        self.statuses = []
        self._sub = rospy.Subscriber("/anyscale/status", ScaleStatus, self._on_status, queue_size=50)

    def _on_status(self, msg):
        if msg.scale == self.scale:
            self.statuses.append(msg)

    def node(self, name):
        for n in self.list().nodes:
            if n.name == name:
                return n
        return None
