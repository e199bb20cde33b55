"""Helpers shared by the agent's rostests: master lookups, waiting, service proxies, raw TCPROS
requests."""
import io
import os
import socket
import struct
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


# anyscale_testbed.system_test_gate's prefix of a test this machine cannot run (the summary of
# scripts/run_tests.sh counts such skips on a line of their own); this package cannot import
# the test bed's.
NOT_RUN = "SYSTEM TEST NOT RUN: "
REQUIRE_ENV = "ANYSCALE_REQUIRE_SYSTEM_TESTS"


def needs_root(test, why):
    """Skips `test` (a unittest.TestCase) unless it runs as root, saying so as a test this
    machine cannot run; with ANYSCALE_REQUIRE_SYSTEM_TESTS=1 (a release check) it fails
    instead."""
    if os.geteuid() == 0:
        return
    if os.environ.get(REQUIRE_ENV, "") not in ("", "0"):
        test.fail(NOT_RUN + why)
    test.skipTest(NOT_RUN + why)


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
        self._sub = rospy.Subscriber("/anyscale/status", ScaleStatus, self._on_status,
                                     queue_size=50)

    def _on_status(self, msg):
        if msg.scale == self.scale:
            self.statuses.append(msg)

    def node(self, name):
        for n in self.list().nodes:
            if n.name == name:
                return n
        return None


def _field_block(fields):
    body = b""
    for key, value in fields.items():
        kv = ("%s=%s" % (key, value)).encode()
        body += struct.pack("<I", len(kv)) + kv
    return struct.pack("<I", len(body)) + body


def _read_exact(sock, n):
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise EOFError("connection closed after %d of %d bytes" % (len(data), n))
        data += chunk
    return data


def raw_service_call(service, md5sum, body, timeout=60.0, master_uri=None,
                     caller="/raw_attacker"):
    """(ok, response bytes) of a TCPROS service request with a hand-made `body`, as any host
    that reaches the service's port may send it (ROS 1 has no authentication); the service is
    looked up on `master_uri` (default: ROS_MASTER_URI)."""
    uri = rosgraph.Master("/agent_test", master_uri=master_uri).lookupService(service)
    host, port = uri[len("rosrpc://"):].rstrip("/").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=timeout) as sock:
        sock.sendall(_field_block({"callerid": caller, "service": service,
                                   "md5sum": md5sum}))
        _read_exact(sock, struct.unpack("<I", _read_exact(sock, 4))[0])   # the server's header
        sock.sendall(struct.pack("<I", len(body)) + body)
        ok = _read_exact(sock, 1)[0]
        return ok, _read_exact(sock, struct.unpack("<I", _read_exact(sock, 4))[0])


def service_call(master_uri, service, srv, timeout=60.0, **fields):
    """The response of `service` (type `srv`) looked up on `master_uri`, called with `fields`:
    one process can call the services of several masters this way, which rospy cannot. Raises
    RuntimeError with the server's text if the call failed."""
    body = io.BytesIO()
    srv._request_class(**fields).serialize(body)
    ok, data = raw_service_call(service, srv._md5sum, body.getvalue(), timeout, master_uri,
                                "/shared_scale_test")
    if not ok:
        raise RuntimeError(f"{service}: {data.decode(errors='replace')}")
    return srv._response_class().deserialize(data)


def peak_rss(pid):
    """VmHWM of a process: the most memory it ever had resident, in bytes."""
    with open("/proc/%d/status" % pid) as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))
