"""master_keeper.py over real XML-RPC on localhost (no roscore): fake masters with rosmaster's
semantics (master_fakes.FakeRosMaster) and fake nodes serve the calls; the keeper takes its
snapshots of one master, says once that it cannot reach it, finds another at the same URI and
puts the snapshot back; a node whose port refuses is gone, one that never answers is silent.
Also the command line."""
import socket
import threading
import xmlrpc.client
from xmlrpc.server import SimpleXMLRPCServer

import pytest

from anyscale_core.master_keeper import MasterClient, MasterKeeper, NodeApi, parse_args
from anyscale_core.master_restore import NodeGone, NodeSilent
from master_fakes import FakeNode, FakeRosMaster

SCAN, T_SCAN = "/scan", "sensor_msgs/LaserScan"


class Served:
    """An object's methods served over XML-RPC on localhost, as rosmaster and every node's API
    are (system.multicall included)."""

    def __init__(self, instance, port=0):
        self.server = SimpleXMLRPCServer(("127.0.0.1", port), logRequests=False, allow_none=True)
        self.server.register_instance(instance)
        self.server.register_multicall_functions()
        self.uri = f"http://127.0.0.1:{self.server.server_address[1]}/"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


class NodeServer:
    """A FakeNode's slave API."""

    def __init__(self, node: FakeNode):
        self.node = node

    def getPublications(self, caller):
        return 1, "", [list(p) for p in self.node.pubs]

    def getSubscriptions(self, caller):
        return 1, "", [list(s) for s in self.node.subs]

    def publisherUpdate(self, caller, topic, uris):
        self.node.publisher_update(topic, uris)
        return 1, "", 0


def publisher_update(uri, topic, uris):
    """The fake master's publisherUpdate, over XML-RPC as rosmaster sends it."""
    try:
        xmlrpc.client.ServerProxy(uri).publisherUpdate("/master", topic, uris)
    except OSError:
        pass


@pytest.fixture
def bed():
    started = []

    def serve(instance, port=0):
        started.append(Served(instance, port))
        return started[-1]
    yield serve
    for s in started:
        s.close()


def node(serve, name, pubs=(), subs=()):
    fake = FakeNode(name, "")
    served = serve(NodeServer(fake))
    fake.uri = served.uri
    fake.pubs, fake.subs = list(pubs), list(subs)
    return fake


def free_port_that_refuses():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_keeper_puts_back_what_a_restarted_master_held_and_says_so_once(bed):
    laser = node(bed, "/laser", pubs=[(SCAN, T_SCAN)])
    amcl = node(bed, "/amcl", subs=[(SCAN, T_SCAN)])
    old = FakeRosMaster(100, "run-a", notify=publisher_update)
    old.params.update({"amcl": {"min_particles": 500}})
    old.registerPublisher("/laser", SCAN, T_SCAN, laser.uri)
    old.registerSubscriber("/amcl", SCAN, T_SCAN, amcl.uri)
    served = bed(old)
    port = served.server.server_address[1]
    lines = []
    keeper = MasterKeeper(MasterClient(served.uri, "/keeper", 2.0),
                          lambda uri: NodeApi(uri, "/keeper", 0.5),
                          lambda level, text: lines.append((level, text)))
    keeper.step()
    assert keeper.snapshot.nodes["/amcl"].uri == amcl.uri and lines == []

    served.close()                              # kill -9 of roscore: nothing answers
    keeper.step()
    keeper.step()
    assert [level for level, _ in lines] == ["WARN"]
    assert "does not answer" in lines[0][1] and "keeping the snapshot of" in lines[0][1]

    new = FakeRosMaster(200, "", notify=publisher_update)     # roscore again, same port
    bed(new, port)
    keeper.step()
    assert lines[1][0] == "WARN" and "restarted (pid 100 -> 200)" in lines[1][1]
    assert lines[2] == ("INFO", "put back 1 parameters and 2 registrations of 2 nodes")
    assert new.params["amcl"] == {"min_particles": 500} and "run_id" not in new.params
    assert new.publishers[SCAN] == [("/laser", laser.uri)]
    assert new.subscribers[SCAN] == [("/amcl", amcl.uri)]
    new.params["run_id"] = "run-b"              # roscore's roslaunch sets it a moment later
    keeper.step()
    keeper.step()
    assert len(lines) == 3                      # the same master: nothing more to say
    assert keeper.snapshot.identity.pid == 200


def test_a_node_api_that_refuses_is_gone_and_one_that_never_answers_is_silent():
    with pytest.raises(NodeGone):
        NodeApi(f"http://127.0.0.1:{free_port_that_refuses()}/", "/k", 0.3).publications()
    with socket.socket() as listening:          # accepted by the kernel, never answered
        listening.bind(("127.0.0.1", 0))
        listening.listen(1)
        uri = f"http://127.0.0.1:{listening.getsockname()[1]}/"
        with pytest.raises(NodeSilent):
            NodeApi(uri, "/k", 0.3).subscriptions()


def test_a_master_that_changes_during_the_snapshots_reads_leaves_the_last_snapshot(bed):
    master = FakeRosMaster(100, "run-a")
    master.registerPublisher("/laser", SCAN, T_SCAN, "http://robot:1/")
    client = MasterClient(bed(master).uri, "/keeper", 2.0)
    assert client.lookups(["/laser"], [], 100) == ({"/laser": "http://robot:1/"}, {})
    assert client.lookups(["/laser"], [], 99) is None


@pytest.mark.parametrize("argv, error", [(["--period", "0"], "--period"),
                                         (["--timeout", "nan"], "--timeout")])
def test_bad_arguments_end_in_one_line(argv, error, capsys):
    with pytest.raises(SystemExit) as done:
        parse_args(argv)
    assert done.value.code == 2 and error in capsys.readouterr().err.splitlines()[-1]


def test_the_defaults_are_a_snapshot_a_second():
    args = parse_args([])
    assert (args.period, args.timeout) == (1.0, 0.5)


def test_registrations_go_in_one_request_each_as_its_node_and_a_raising_one_fails_alone(bed):
    class Raising(FakeRosMaster):
        def registerPublisher(self, caller, topic, type_, uri):
            if topic == "/bad":
                raise ValueError("no such type")
            return super().registerPublisher(caller, topic, type_, uri)

    master = Raising(100, "run-a")
    client = MasterClient(bed(master).uri, "/keeper", 2.0)
    replies = client.register([("registerPublisher", "/laser", (SCAN, T_SCAN, "http://r:1/")),
                               ("registerPublisher", "/relay", ("/bad", T_SCAN, "http://r:2/")),
                               ("registerSubscriber", "/amcl", (SCAN, T_SCAN, "http://r:3/"))])
    assert replies[0] == [] and replies[2] == ["http://r:1/"]
    assert "no such type" in str(replies[1])
    assert master.nodes == {"/laser": "http://r:1/", "/amcl": "http://r:3/"}
    assert client.held_registrations() == {"/laser": {("pub", SCAN)}, "/amcl": {("sub", SCAN)}}
