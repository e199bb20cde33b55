"""master_restore.py (no roscore): a new master told from the old one, the parameters a new
master lacks, the snapshot, and the restore on a fake master with rosmaster's semantics and
nodes that keep their connections as roscpp does."""
import pytest

from anyscale_core.master_restore import (MasterIdentity, is_new_master, missing_params, restore,
                                          take_snapshot)
from master_fakes import Direct, FakeGraph, FakeNode, FakeRosMaster

SCAN, POSE, OUT = "/scan", "/amcl_pose", "/rosout"
T_SCAN, T_POSE, T_LOG = "sensor_msgs/LaserScan", "geometry_msgs/PoseWithCovarianceStamped", \
    "rosgraph_msgs/Log"


def test_another_pid_or_another_run_id_is_a_new_master_and_run_id_appearing_is_not():
    old = MasterIdentity(100, "run-a")
    assert not is_new_master(None, old)
    assert not is_new_master(old, MasterIdentity(100, "run-a"))
    assert is_new_master(old, MasterIdentity(200, ""))          # roslaunch not yet at /run_id
    assert is_new_master(old, MasterIdentity(100, "run-b"))     # same pid, in a new container
    assert not is_new_master(MasterIdentity(200, ""), MasterIdentity(200, "run-b"))


def test_missing_parameters_are_put_back_and_the_new_masters_own_are_kept():
    saved = {"run_id": "old", "rosversion": "1.15.14",
             "amcl": {"min_particles": 500, "laser": {"beams": 30}},
             "anyscale": {"model": "/m.yaml"}}
    current = {"run_id": "new", "rosversion": "1.15.15", "amcl": {"min_particles": 100}}
    assert missing_params(saved, current) == [("/amcl/laser", {"beams": 30}),
                                              ("/anyscale", {"model": "/m.yaml"})]
    assert missing_params(saved, {}) == [("/amcl", saved["amcl"]), ("/anyscale", saved["anyscale"]),
                                         ("/rosversion", "1.15.14")]    # never /run_id


def graph_before():
    """The old master's graph: the laser publishes /scan, which AMCL and navigation take; a
    second publisher of /scan (a relay); AMCL publishes its pose; a node that has ended."""
    laser = FakeNode("/laser", "http://robot:1/", [(SCAN, T_SCAN), (OUT, T_LOG)])
    relay = FakeNode("/relay", "http://robot:2/", [(SCAN, T_SCAN)])
    amcl = FakeNode("/amcl", "http://laptop:3/", [(POSE, T_POSE)], [(SCAN, T_SCAN)],
                    connected={SCAN: {laser.uri, relay.uri}})
    nav = FakeNode("/navigation", "http://robot:4/", [], [(SCAN, T_SCAN), (POSE, T_POSE)],
                   connected={SCAN: {laser.uri, relay.uri}, POSE: {amcl.uri}})
    ended = FakeNode("/ended", "http://robot:5/", [(POSE, T_POSE)])
    return [laser, relay, amcl, nav, ended]


def old_master(nodes):
    m = FakeRosMaster(100, "run-a")
    m.params.update({"amcl": {"min_particles": 500}, "rosversion": "1.15.15"})
    for n in nodes:
        for topic, type_ in n.pubs:
            m.registerPublisher(n.name, topic, type_, n.uri)
        for topic, type_ in n.subs:
            m.registerSubscriber(n.name, topic, type_, n.uri)
    m.registerService("/anyscale_agent_robot", "/anyscale/robot/start_node", "rosrpc://robot:9",
                      "http://robot:6/")
    m.nodes["/anyscale_agent_robot"] = "http://robot:6/"
    return m


def snapshot_of(m: FakeRosMaster):
    state = m.getSystemState("/k")[2]
    names = {n for kind in state for _, ns in kind for n in ns}
    return take_snapshot(MasterIdentity(m.pid, m.params.get("run_id", "")), 0.0, m.params, state,
                         m.getTopicTypes("/k")[2], {n: m.lookupNode("/k", n)[2] for n in names},
                         {s: m.lookupService("/k", s)[2] for s, _ in state[2]})


def restarted(nodes, gone=(), silent=()):
    """(new master, graph, snapshot of the old one): the old master knew `nodes`; the new one
    has roscore's parameters only; `gone` URIs refuse, `silent` ones do not answer."""
    snapshot = snapshot_of(old_master(nodes))
    graph = FakeGraph(nodes + [FakeNode("/anyscale_agent_robot", "http://robot:6/")], gone,
                      silent)
    new = FakeRosMaster(200, "run-b", notify=graph.notify)
    new.params["rosversion"] = "1.15.15"
    return new, graph, snapshot


def test_the_snapshot_holds_each_nodes_uri_topics_types_and_services():
    snap = snapshot_of(old_master(graph_before()))
    assert snap.nodes["/amcl"].uri == "http://laptop:3/"
    assert snap.nodes["/amcl"].publications == [(POSE, T_POSE)]
    assert snap.nodes["/navigation"].subscriptions == [(POSE, T_POSE), (SCAN, T_SCAN)]
    assert snap.nodes["/anyscale_agent_robot"].services == [("/anyscale/robot/start_node",
                                                             "rosrpc://robot:9")]
    assert snap.publisher_uris[SCAN] == {"http://robot:1/", "http://robot:2/"}


def test_a_restarted_master_gets_the_parameters_and_every_live_nodes_registrations_back():
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes, gone={"http://robot:5/"})
    report = restore(Direct(new), graph.api, snapshot)
    assert new.params["amcl"] == {"min_particles": 500} and new.params["run_id"] == "run-b"
    assert report.params == 1
    assert report.gone == ["/ended"] and "/ended" not in new.nodes
    assert sorted(n for n, _ in new.publishers[SCAN]) == ["/laser", "/relay"]
    assert sorted(n for n, _ in new.subscribers[SCAN]) == ["/amcl", "/navigation"]
    assert new.publishers[POSE] == [("/amcl", "http://laptop:3/")]
    assert new.services["/anyscale/robot/start_node"] == ("/anyscale_agent_robot",
                                                          "rosrpc://robot:9")
    assert new.nodes["/navigation"] == "http://robot:4/"
    assert new.shutdowns == [] and report.failures == []


def test_no_subscriber_loses_a_connection_while_the_registrations_come_back():
    # roscpp drops a publisher missing from a publisherUpdate: registering a subscriber before
    # every publisher of its topic would cut /navigation from one of the two /scan publishers.
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes)
    restore(Direct(new), graph.api, snapshot)
    assert [n.dropped for n in nodes] == [[]] * len(nodes)
    assert nodes[3].connected[SCAN] == {"http://robot:1/", "http://robot:2/"}


def test_a_subscriber_is_told_of_a_publisher_that_registered_with_the_new_master_first():
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes)
    # A relay respawned while the master was down registered itself, under a new URI.
    respawned = FakeNode("/relay", "http://robot:7/", [(SCAN, T_SCAN)])
    graph.nodes[respawned.uri] = respawned
    new.registerPublisher("/relay", SCAN, T_SCAN, respawned.uri)
    report = restore(Direct(new), graph.api, snapshot)
    assert "/relay" in report.already and new.shutdowns == []    # the new process stays
    assert nodes[3].connected[SCAN] == {"http://robot:1/", "http://robot:7/"}
    assert report.updates == 2                                   # /amcl and /navigation


def test_a_node_that_does_not_answer_is_registered_as_the_snapshot_had_it():
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes, silent={"http://laptop:3/"})   # AMCL, paused
    report = restore(Direct(new), graph.api, snapshot)
    assert report.unanswered == ["/amcl"]
    assert ("/amcl", "http://laptop:3/") in new.publishers[POSE]
    assert ("/amcl", "http://laptop:3/") in new.subscribers[SCAN]
    assert "did not answer: as the snapshot had them" in report.describe()


def test_a_node_reports_its_current_topics_over_the_snapshots():
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes)
    nodes[2].pubs.append(("/particlecloud", "geometry_msgs/PoseArray"))   # since the snapshot
    restore(Direct(new), graph.api, snapshot)
    assert new.publishers["/particlecloud"] == [("/amcl", "http://laptop:3/")]


def test_a_registration_the_master_refuses_is_reported_and_the_others_go_on():
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes, gone={"http://robot:5/"})
    new.refuse.add(POSE)
    report = restore(Direct(new), graph.api, snapshot)
    assert report.failures == [f"/amcl {POSE}: refused {POSE}"]
    assert len(new.publishers[SCAN]) == 2
    assert "FAILED: /amcl /amcl_pose: refused /amcl_pose" in report.describe()


@pytest.mark.parametrize("order", ["nodes", "reversed"])
def test_restoring_twice_changes_nothing_the_second_time(order):
    nodes = graph_before()
    new, graph, snapshot = restarted(nodes if order == "nodes" else nodes[::-1])
    restore(Direct(new), graph.api, snapshot)
    again = restore(Direct(new), graph.api, snapshot)
    assert again.params == 0 and again.nodes == [] and again.registrations == 0
    assert len(new.publishers[SCAN]) == 2 and new.shutdowns == []
