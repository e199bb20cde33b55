"""The three-scale bed's network for real (root, network namespaces, tc; access_point_layout.py):
the server is reached from the robot through the WiFi hop, which limits and cuts that traffic as
it does the laptop's, while laptop - server traffic stays on the wired side; the server's segment
carries its 100 Mbit/s tbf on both ends; teardown leaves nothing. Its own names and subnet
(process_access_point_layout), no CPU quotas: it may run beside a test bed."""
import os

import pytest

from anyscale_testbed.access_point_layout import process_access_point_layout
from anyscale_testbed.system_test_gate import NOT_RUN
from anyscale_testbed.two_scale_testbed import TwoScaleTestbed, missing_capabilities, run

import tcp_byte_counter

MISSING = missing_capabilities(need_cgroups=False)
pytestmark = pytest.mark.skipif(bool(MISSING), reason=NOT_RUN + "this machine lacks " +
                                "; ".join(MISSING))

TAG = "astb"
LAYOUT = process_access_point_layout(TAG, "10.213.94", os.getpid())
ROBOT, LAPTOP, SERVER = LAYOUT.ends

PORT = 7701


def send_bytes(sender, size):
    """`size` bytes from the scale end `sender` to the server: (bytes received, seconds), or
    (None, None) if they could not be sent."""
    return tcp_byte_counter.send_bytes(sender.namespace, SERVER.address, PORT, size, 20)


def leftovers():
    left = [ns for ns in run(["ip", "netns", "list"]).stdout.split()
            if ns.startswith(f"{TAG}{os.getpid()}_")]
    return left + [n for n in LAYOUT.interfaces
                   if run(["ip", "link", "show", n], check=False).returncode == 0]


def test_the_server_is_behind_the_wifi_hop_and_the_wired_segment(tmp_path):
    with TwoScaleTestbed(LAYOUT, cgroup_prefix=f"{TAG}{os.getpid()}") as bed:
        listener = tcp_byte_counter.start_listener(bed, "server", SERVER.address, PORT,
                                                   tmp_path / "listener.log")
        for end, port in ((SERVER.namespace, SERVER.interface),
                          (LAYOUT.ap_namespace, LAYOUT.remotes[1].port)):
            shown = run(["ip", "netns", "exec", end, "tc", "qdisc", "show", "dev", port]).stdout
            assert "tbf" in shown and "rate 100Mbit" in shown, shown
        assert send_bytes(ROBOT, 100_000)[0] == 100_000
        bed.shape(1.0)                                      # the WiFi hop at 1 Mbit/s
        received, seconds = send_bytes(ROBOT, 500_000)      # 4 Mbit
        assert received == 500_000 and seconds > 2.0
        received, seconds = send_bytes(LAPTOP, 500_000)     # the wired side: not limited
        assert received == 500_000 and seconds < 2.0
        bed.set_link(False)                                 # no coverage: the robot is cut off
        assert send_bytes(ROBOT, 1000) == (None, None)
        assert send_bytes(LAPTOP, 1000)[0] == 1000
        bed.set_link(True)
        bed.shape(50.0)
        assert send_bytes(ROBOT, 1000)[0] == 1000
        assert listener.poll() is None
    assert leftovers() == []
    assert bed.teardown() == []                             # and again: nothing to do
