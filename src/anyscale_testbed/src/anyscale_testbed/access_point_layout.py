"""The three-scale test bed's network (issue 39): the robot, the laptop and a server as network
namespaces behind a WiFi access point, as argv lists (no shell), pure: building them needs no
root. two_scale_testbed.TwoScaleTestbed sets up and tears down this layout as it does the
two-scale one (both give it `ends`, `namespaces`, `interfaces`, `wifi_link`, `setup_commands()`).

    anyscale_robot           anyscale_ap (the access point)        anyscale_laptop, _server
    asv_robot .1 ~~ WiFi ~~ asv_ap_robot --+                +-- asv_ap_laptop --- asv_laptop .2
                                           +-- asv_bridge --+
                                                            +-- asv_ap_server === asv_server .3
    (10.213.7.0/24; ~~ the link shaper's WiFi hop, === the wired segment at 100 Mbit/s)

Why a bridge, not a router. An access point in infrastructure mode is a layer-2 bridge between
its radio and its Ethernet port, and a Linux bridge in a namespace of its own is that: the three
scales share one /24, as the two-scale bed's two do, so each scale's ROS_IP, the master's
address and the agents' link probes are what they were, with no subnet per segment, no routes in
every scale and no ip_forward. A router namespace would add an IP hop a real AP does not have.

- The WiFi hop is the veth robot - AP (`wifi_link`). The link shaper sets it as it sets the
  two-scale bed's robot-laptop veth (testbed_world.launch's `wifi_peer_*` args name the AP's
  end): tbf on both ends, both ends down where the coverage model has no link. So every stream
  between the robot and either remote scale crosses it, both ways, and they share its rate, as
  they share one radio; when the robot's WiFi goes, both remote scales go with it.
- The laptop's segment is not shaped: on the two-scale bed only the robot's WiFi is either, so
  the robot-laptop traffic meets the same shaping on both beds (the bridge adds microseconds).
- The server's wired segment: tbf at WIRED_MBPS on both of its ends, set once with the layout.

Delay: not modelled, and it cannot be here. This kernel has no netem, nor any qdisc that holds a
packet until a time (/proc/config.gz: NET_SCH_NETEM, _ETF, _TAPRIO and _FQ are not set). tbf's
`latency` is not a delay: it is the longest a packet may wait in the bucket's queue before it is
dropped, a bound on queueing under load (at 100 Mbit/s, 50 ms is 625 KB). A delay line in user space
(a TAP pair and a process holding each frame a few ms) would copy every camera frame through a
Python process on the 2 cores the bed's quotas share, and add its own scheduling jitter. So the
wired segment has a veth's own delay (tens of microseconds) instead of a few ms. What the
decision node acts on hardly sees the difference: tolerances are 1-2 s, status comes every
0.2-0.5 s, a link probe counts as lost after 1-2 s, and the WiFi hop's own tbf queue, up to
50 ms, is ten times that delay. Where netem exists, `netem delay 2ms` as tbf's child qdisc on
both ends of the segment would add it.
"""
from dataclasses import dataclass
from typing import List, Mapping, Tuple

from .two_scale_testbed import (DEFAULT_AP_NAMESPACE, DEFAULT_SERVER_NAMESPACE, ScaleEnd,
                                TwoScaleLayout, shape_commands)

# The wired segment between the access point and the server: switched Fast Ethernet.
WIRED_MBPS = 100.0
# tc-tbf(8): the bucket must hold at least rate / HZ, or the rate is not reached; this kernel
# ticks at 250 Hz, and 100 Mbit/s / 250 = 400 kbit (50 KB).
WIRED_BURST_KBIT = 400
IFNAMSIZ = 16                   # an interface name has at most 15 characters


@dataclass(frozen=True)
class Attachment:
    """A scale's veth to the access point: its end, in the scale's namespace, and the AP's end,
    a port of the AP's bridge."""
    end: ScaleEnd
    port: str
    wired_mbps: float = 0.0     # tbf rate of this segment, both ways; 0: not shaped here


@dataclass(frozen=True)
class AccessPointLayout:
    """The robot (the WiFi station) and the remote scales behind the access point. The station's
    segment is the WiFi hop, which the link shaper sets; each remote's is wired, shaped at its
    `wired_mbps` or not at all."""
    station: Attachment
    remotes: Tuple[Attachment, ...]
    ap_namespace: str = DEFAULT_AP_NAMESPACE
    bridge: str = "asv_bridge"
    prefix_len: int = 24

    def __post_init__(self):
        scales = [a.end.scale for a in self.attachments]
        if len(set(scales)) != len(scales):
            raise ValueError(f"a scale appears twice: {', '.join(scales)}")
        too_long = [n for n in self.interfaces + (self.bridge,) if len(n) >= IFNAMSIZ]
        if too_long:
            raise ValueError(f"interface names longer than {IFNAMSIZ - 1} characters: "
                             f"{', '.join(too_long)}")
        if self.station.wired_mbps:
            raise ValueError("the station's segment is the WiFi hop: the link shaper sets it")

    @property
    def attachments(self) -> Tuple[Attachment, ...]:
        return (self.station,) + tuple(self.remotes)

    @property
    def robot(self) -> ScaleEnd:
        return self.station.end

    @property
    def ends(self) -> Tuple[ScaleEnd, ...]:
        """The scales' ends, robot first: where their processes run."""
        return tuple(a.end for a in self.attachments)

    @property
    def namespaces(self) -> Tuple[str, ...]:
        return tuple(e.namespace for e in self.ends) + (self.ap_namespace,)

    @property
    def interfaces(self) -> Tuple[str, ...]:
        """Both ends of every veth: a setup that failed before moving them leaves them in the
        root namespace, where the teardown looks for them."""
        return tuple(n for a in self.attachments for n in (a.end.interface, a.port))

    @property
    def wifi_link(self) -> TwoScaleLayout:
        """The WiFi hop's two ends, the pair the link shaper sets: the robot's and the AP's."""
        return TwoScaleLayout(self.robot, self._ap_end(self.station), self.prefix_len)

    def _ap_end(self, a: Attachment) -> ScaleEnd:
        return ScaleEnd("access_point", self.ap_namespace, a.port, "", 0.0)

    def setup_commands(self) -> List[List[str]]:
        """Namespaces, the AP's bridge, a veth per scale with its AP end on the bridge, the
        scales' addresses, then the wired segments' shaping. The WiFi is left to the shaper."""
        ap = self.ap_namespace
        cmds = [["ip", "netns", "add", ns] for ns in self.namespaces]
        cmds.append(["ip", "-n", ap, "link", "add", self.bridge, "type", "bridge"])
        for a in self.attachments:
            end = a.end
            cmds += [["ip", "link", "add", end.interface, "type", "veth", "peer", "name",
                      a.port],
                     ["ip", "link", "set", end.interface, "netns", end.namespace],
                     ["ip", "link", "set", a.port, "netns", ap],
                     ["ip", "-n", ap, "link", "set", a.port, "master", self.bridge],
                     ["ip", "-n", ap, "link", "set", a.port, "up"],
                     ["ip", "-n", end.namespace, "addr", "add",
                      f"{end.address}/{self.prefix_len}", "dev", end.interface],
                     ["ip", "-n", end.namespace, "link", "set", "lo", "up"],
                     ["ip", "-n", end.namespace, "link", "set", end.interface, "up"]]
        # Without STP (a new bridge's default) a port forwards as soon as it is up: the WiFi's
        # link up after an outage passes traffic at once, as on the two-scale bed's veth.
        cmds.append(["ip", "-n", ap, "link", "set", self.bridge, "up"])
        return cmds + self.wired_commands()

    def wired_commands(self) -> List[List[str]]:
        """tbf on both ends of each shaped wired segment (the scale's end and the AP's port)."""
        cmds = []
        for a in self.remotes:
            if a.wired_mbps > 0:
                pair = TwoScaleLayout(a.end, self._ap_end(a), self.prefix_len)
                cmds += shape_commands(pair, a.wired_mbps, WIRED_BURST_KBIT)
        return cmds


# The server's end on the default bed: beside the two-scale bed's robot (.1) and laptop (.2).
SERVER_END = ScaleEnd("server", DEFAULT_SERVER_NAMESPACE, "asv_server", "10.213.7.3", 0.0)


def access_point_layout(cores: Mapping[str, float], wired_mbps: float = WIRED_MBPS,
                        base: TwoScaleLayout = TwoScaleLayout()) -> AccessPointLayout:
    """The three-scale bed: the two-scale bed's robot and laptop ends (names, addresses), the
    server's, each with its CPU quota from `cores` (scale -> cores, 0 or absent: none); the
    server's segment at `wired_mbps` (0: not shaped, as with --link unshaped)."""
    def attach(end: ScaleEnd, mbps: float = 0.0) -> Attachment:
        return Attachment(ScaleEnd(end.scale, end.namespace, end.interface, end.address,
                                   float(cores.get(end.scale, 0.0))),
                          f"asv_ap_{end.scale}", mbps)
    return AccessPointLayout(attach(base.robot),
                             (attach(base.laptop), attach(SERVER_END, wired_mbps)),
                             prefix_len=base.prefix_len)


def process_access_point_layout(tag: str, subnet: str, pid: int,
                                wired_mbps: float = WIRED_MBPS) -> AccessPointLayout:
    """A three-scale layout no other bed on the machine uses (the counterpart of
    two_scale_testbed.process_layout): names from `tag` (up to 5 characters) and `pid`,
    addresses .1 (robot), .2 (laptop), .3 (server) of its own /24 `subnet`."""
    def attach(scale: str, letter: str, host: int, mbps: float = 0.0) -> Attachment:
        return Attachment(ScaleEnd(scale, f"{tag}{pid}_{letter}", f"{tag}{pid}{letter}",
                                   f"{subnet}.{host}", 0.0), f"{tag}{pid}a{letter}", mbps)
    return AccessPointLayout(attach("robot", "r", 1),
                             (attach("laptop", "l", 2), attach("server", "s", 3, wired_mbps)),
                             ap_namespace=f"{tag}{pid}_ap", bridge=f"{tag}{pid}b")
