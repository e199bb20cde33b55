"""The three-scale bed's network as argv lists (access_point_layout.py), no root: namespaces, the
access point's bridge, a veth per scale with its AP end on the bridge, the server's wired
segment shaped on both ends, the WiFi hop the link shaper sets; and that the two-scale layout
gives the bed what it always did. Nothing here runs a command."""
import pytest

from anyscale_testbed import two_scale_testbed
from anyscale_testbed.access_point_layout import (WIRED_BURST_KBIT, AccessPointLayout,
                                                  Attachment, access_point_layout,
                                                  process_access_point_layout)
from anyscale_testbed.link_shaper import LinkSetting, setting_commands
from anyscale_testbed.two_scale_testbed import (ScaleEnd, TwoScaleLayout, TwoScaleTestbed,
                                                setup_commands)

LAYOUT = access_point_layout({"robot": 0.34, "laptop": 0.9, "server": 0.5})


def argv_strings(cmds):
    return all(isinstance(cmd, list) and all(isinstance(a, str) for a in cmd) for cmd in cmds)


def test_the_default_three_scale_bed_keeps_the_two_scale_names_and_adds_the_server():
    two = TwoScaleLayout()
    assert [e.scale for e in LAYOUT.ends] == ["robot", "laptop", "server"]
    assert LAYOUT.robot == ScaleEnd("robot", "anyscale_robot", "asv_robot", "10.213.7.1", 0.34)
    assert LAYOUT.ends[1] == ScaleEnd("laptop", two.laptop.namespace, two.laptop.interface,
                                      two.laptop.address, 0.9)
    assert LAYOUT.ends[2] == ScaleEnd("server", "anyscale_server", "asv_server", "10.213.7.3",
                                      0.5)
    assert LAYOUT.namespaces == ("anyscale_robot", "anyscale_laptop", "anyscale_server",
                                 "anyscale_ap")
    assert LAYOUT.interfaces == ("asv_robot", "asv_ap_robot", "asv_laptop", "asv_ap_laptop",
                                 "asv_server", "asv_ap_server")
    assert [a.wired_mbps for a in LAYOUT.remotes] == [0.0, 100.0]


def test_setup_builds_the_bridge_then_each_scales_veth_then_shapes_the_wired_segment():
    cmds = LAYOUT.setup_commands()
    assert argv_strings(cmds)
    assert cmds[:4] == [["ip", "netns", "add", ns] for ns in LAYOUT.namespaces]
    assert cmds[4] == ["ip", "-n", "anyscale_ap", "link", "add", "asv_bridge", "type", "bridge"]
    server = cmds.index(["ip", "link", "add", "asv_server", "type", "veth", "peer", "name",
                         "asv_ap_server"])
    assert cmds[server:server + 8] == [
        ["ip", "link", "add", "asv_server", "type", "veth", "peer", "name", "asv_ap_server"],
        ["ip", "link", "set", "asv_server", "netns", "anyscale_server"],
        ["ip", "link", "set", "asv_ap_server", "netns", "anyscale_ap"],
        ["ip", "-n", "anyscale_ap", "link", "set", "asv_ap_server", "master", "asv_bridge"],
        ["ip", "-n", "anyscale_ap", "link", "set", "asv_ap_server", "up"],
        ["ip", "-n", "anyscale_server", "addr", "add", "10.213.7.3/24", "dev", "asv_server"],
        ["ip", "-n", "anyscale_server", "link", "set", "lo", "up"],
        ["ip", "-n", "anyscale_server", "link", "set", "asv_server", "up"]]
    for end in LAYOUT.ends:             # every scale gets its veth on the bridge and its address
        assert ["ip", "-n", "anyscale_ap", "link", "set", f"asv_ap_{end.scale}", "master",
                "asv_bridge"] in cmds
        assert ["ip", "-n", end.namespace, "addr", "add", f"{end.address}/24", "dev",
                end.interface] in cmds
    bridge_up = cmds.index(["ip", "-n", "anyscale_ap", "link", "set", "asv_bridge", "up"])
    # The wired segment's tbf, on the server's end and the AP's port, after everything is up.
    assert cmds[bridge_up + 1:] == LAYOUT.wired_commands()
    assert [c[3:8] for c in LAYOUT.wired_commands()] == [
        ["anyscale_server", "tc", "qdisc", "replace", "dev"],
        ["anyscale_ap", "tc", "qdisc", "replace", "dev"]]
    assert [c[8] for c in LAYOUT.wired_commands()] == ["asv_server", "asv_ap_server"]
    assert all(c[-8:] == ["root", "tbf", "rate", "100000kbit", "burst",
                          f"{WIRED_BURST_KBIT}kbit", "latency", "50ms"]
               for c in LAYOUT.wired_commands())
    # Nothing at setup touches the WiFi hop's rate: the link shaper sets it.
    assert not any("tbf" in c and ("asv_robot" in c or "asv_ap_robot" in c) for c in cmds)
    assert not any(c[:2] == ["ip", "netns"] and "exec" in c and "sh" in c for c in cmds)


def test_the_wifi_link_is_the_robots_veth_to_the_access_point():
    wifi = LAYOUT.wifi_link
    assert [(e.namespace, e.interface) for e in wifi.ends] == [
        ("anyscale_robot", "asv_robot"), ("anyscale_ap", "asv_ap_robot")]
    # The link shaper's commands for a change, on that pair: both ends, as on the veth pair.
    cmds = setting_commands(wifi, None, LinkSetting(True, 6.0))
    assert [(c[3], c[8], c[c.index("rate") + 1]) for c in cmds[:2]] == [
        ("anyscale_robot", "asv_robot", "6000kbit"), ("anyscale_ap", "asv_ap_robot", "6000kbit")]
    assert setting_commands(wifi, LinkSetting(True, 6.0), LinkSetting(False)) == [
        ["ip", "-n", "anyscale_robot", "link", "set", "asv_robot", "down"],
        ["ip", "-n", "anyscale_ap", "link", "set", "asv_ap_robot", "down"]]


def test_an_unshaped_run_leaves_the_wired_segment_unshaped_too():
    unshaped = access_point_layout({}, wired_mbps=0.0)
    assert unshaped.wired_commands() == []
    assert not any("tbf" in c for c in unshaped.setup_commands())
    assert all(e.cpu_cores == 0.0 for e in unshaped.ends)


def test_the_bed_takes_a_quota_per_scale_and_shapes_the_wifi_hop(monkeypatch):
    """TwoScaleTestbed on the three-scale layout, without entering it (no command is run)."""
    ran = []
    monkeypatch.setattr(two_scale_testbed, "run", lambda argv, check=True: ran.append(argv))
    bed = TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_u")
    assert {s: q.cores for s, q in bed.quotas.items()} == {"robot": 0.34, "laptop": 0.9,
                                                           "server": 0.5}
    assert bed.quotas["server"].path.endswith("/anyscale_u_server")
    assert bed.end("server").address == "10.213.7.3"
    bed.shape(3.0)
    bed.set_link(False)
    assert [(c[3] if "tbf" in c else c[2], c[-1]) for c in ran] == [
        ("anyscale_robot", "50ms"), ("anyscale_ap", "50ms"),
        ("anyscale_robot", "down"), ("anyscale_ap", "down")]


def test_the_two_scale_layout_gives_the_bed_what_it_always_did():
    two = TwoScaleLayout()
    assert two.setup_commands() == setup_commands(two)
    assert two.namespaces == ("anyscale_robot", "anyscale_laptop")
    assert two.interfaces == ("asv_robot", "asv_laptop")
    assert two.wifi_link is two


def test_a_process_layout_is_its_own_and_fits_interface_names():
    layout = process_access_point_layout("asap", "10.213.93", pid=4194304)
    names = set(layout.interfaces) | {layout.bridge}
    assert len(names) == 7 and all(len(n) <= 15 for n in names)
    default_names = set(LAYOUT.interfaces) | {LAYOUT.bridge} | set(LAYOUT.namespaces)
    assert not (names | set(layout.namespaces)) & default_names
    assert [e.address for e in layout.ends] == ["10.213.93.1", "10.213.93.2", "10.213.93.3"]


@pytest.mark.parametrize("remotes,message", [
    ((Attachment(ScaleEnd("robot", "n2", "i2", "10.0.0.2", 0), "p2"),), "a scale appears twice"),
    ((Attachment(ScaleEnd("laptop", "n2", "an_interface_name", "10.0.0.2", 0), "p2"),),
     "longer than 15 characters: an_interface_name"),
])
def test_a_layout_that_cannot_be_built_says_why(remotes, message):
    station = Attachment(ScaleEnd("robot", "n1", "i1", "10.0.0.1", 0), "p1")
    with pytest.raises(ValueError, match=message):
        AccessPointLayout(station, remotes)
    with pytest.raises(ValueError, match="the station's segment is the WiFi hop"):
        AccessPointLayout(Attachment(station.end, "p1", 100.0), ())


def test_either_default_bed_removes_what_a_killed_run_of_the_other_left():
    # Both take the robot namespace's lock; a bed of its own removes only its own names.
    for layout in (TwoScaleLayout(), LAYOUT):
        assert set(LAYOUT.namespaces) | set(TwoScaleLayout().namespaces) <= set(
            two_scale_testbed.leftover_namespaces(layout))
    mine = process_access_point_layout("astb", "10.213.94", 4242)
    assert two_scale_testbed.leftover_namespaces(mine) == ()
    assert two_scale_testbed.leftover_namespaces(two_scale_testbed.process_layout(
        "tst", "10.213.95", 4242)) == ()
