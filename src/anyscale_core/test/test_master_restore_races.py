"""master_restore.py (no roscore) when the graph does not hold still around a restore: nodes
that answer slowly or not at all (a starved robot, an instance paused with SIGSTOP), nodes that
registered with the new master by themselves before the restore, a restore the master broke
off, and a node whose process was replaced while the others were being asked."""
import contextlib
import time

from anyscale_core.master_restore import NodeSilent, restore
from master_fakes import Direct, FakeNode
from test_master_restore import POSE, SCAN, T_POSE, T_SCAN, graph_before, restarted

CLOUD, T_CLOUD = "/particlecloud", "geometry_msgs/PoseArray"


class Slow:
    """A node's API that takes `delay_s` per call, or, silent, `delay_s` and then no answer (a
    call that timed out)."""

    def __init__(self, node, delay_s, silent=False):
        self.node, self.delay_s, self.silent = node, delay_s, silent

    def _answer(self, value):
        time.sleep(self.delay_s)
        if self.silent:
            raise NodeSilent(self.node.uri)
        return value

    def publications(self):
        return self._answer(self.node.publications())

    def subscriptions(self):
        return self._answer(self.node.subscriptions())

    def publisher_update(self, topic, uris):
        self._answer(self.node.publisher_update(topic, uris))


def test_nodes_are_asked_at_once_so_a_silent_one_costs_one_timeout_in_all():
    # A robot instance paused at home (SIGSTOP) beside the laptop's instance of the same node,
    # and a dozen starved nodes each answering after 0.2 s: asked one after the other this
    # took 0.5 s + 12 x 2 x 0.2 s.
    nodes = graph_before()
    paused = FakeNode("/amcl_robot", "http://robot:8/", [(POSE, T_POSE)], [(SCAN, T_SCAN)])
    starved = [FakeNode(f"/n{i}", f"http://robot:{20 + i}/", [(f"/t{i}", T_SCAN)])
               for i in range(12)]
    new, graph, snapshot = restarted(nodes + [paused] + starved, gone={"http://robot:5/"})
    nodes[2].pubs.append((CLOUD, T_CLOUD))      # the laptop's instance, since the snapshot

    def api(uri):
        if uri == paused.uri:
            return Slow(paused, 0.5, silent=True)
        return Slow(graph.api(uri), 0.2 if uri.startswith("http://robot:2") else 0.0)

    began = time.monotonic()
    report = restore(Direct(new), api, snapshot)
    assert time.monotonic() - began < 1.5
    assert report.unanswered == ["/amcl_robot"] and report.failures == []
    assert sorted(new.publishers[POSE]) == [("/amcl", "http://laptop:3/"),
                                            ("/amcl_robot", "http://robot:8/")]
    assert new.publishers[CLOUD] == [("/amcl", "http://laptop:3/")]
    assert all(new.publishers[f"/t{i}"] for i in range(12)) and new.shutdowns == []


def test_a_node_that_registered_again_by_itself_under_its_uri_gets_the_rest_back():
    # AMCL resumed from its pause subscribes to /scan again: that registers it with the new
    # master before the restore, which then took it for a new process and left its
    # publication of /amcl_pose unregistered.
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes, gone={"http://robot:5/"})
    new.registerSubscriber("/amcl", SCAN, T_SCAN, "http://laptop:3/")
    report = restore(Direct(new), graph.api, snapshot)
    assert new.publishers[POSE] == [("/amcl", "http://laptop:3/")]
    assert new.subscribers[SCAN].count(("/amcl", "http://laptop:3/")) == 1
    assert "/amcl" not in report.already and new.shutdowns == []


class BreaksOff(Direct):
    """The master stops answering after `calls` registrations (it went again, or it did not
    answer within the keeper's timeout)."""

    def __init__(self, master, calls):
        super().__init__(master)
        self.left = calls

    def register(self, calls):
        if self.left < len(calls):
            raise OSError("the master does not answer")
        self.left -= len(calls)
        return super().register(calls)


def test_a_restore_the_master_broke_off_is_completed_by_the_next_one():
    for calls in range(12):
        new, graph, snapshot = restarted(graph_before(), gone={"http://robot:5/"})
        with contextlib.suppress(OSError):
            restore(BreaksOff(new, calls), graph.api, snapshot)
        restore(Direct(new), graph.api, snapshot)
        assert sorted(n for n, _ in new.subscribers[SCAN]) == ["/amcl", "/navigation"], calls
        assert sorted(n for n, _ in new.subscribers[POSE]) == ["/navigation"]
        assert sorted(n for n, _ in new.publishers[SCAN]) == ["/laser", "/relay"]
        assert new.publishers[POSE] == [("/amcl", "http://laptop:3/")]


def test_a_process_that_took_its_name_while_the_nodes_were_asked_is_not_shut_down():
    # The relay respawned (a new process, a new URI) while the restore was asking the others:
    # registering the snapshot's URI under its name now would make the master shut it down.
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes)
    respawned = FakeNode("/relay", "http://robot:7/", [(SCAN, T_SCAN)])
    graph.nodes[respawned.uri] = respawned
    laser_api = graph.api("http://robot:1/")

    class Respawning:
        def publications(self):
            new.registerPublisher("/relay", SCAN, T_SCAN, respawned.uri)
            return laser_api.publications()

        def subscriptions(self):
            return laser_api.subscriptions()

    def api(uri):
        return Respawning() if uri == "http://robot:1/" else graph.api(uri)

    report = restore(Direct(new), api, snapshot)
    assert new.shutdowns == [] and "/relay" in report.already
    assert ("/relay", "http://robot:7/") in new.publishers[SCAN]
