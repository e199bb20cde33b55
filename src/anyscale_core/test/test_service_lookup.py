"""The decision node's calls to the agents' services across a roscore restart (no roscore: the
master's lookupService and the service's connection are faked where rospy makes them). rospy
asks the master for a service's URI at every call; a master that is gone, or restarted and not
yet given back its registrations by the master keeper, answered none, lease renewals failed
for as long, and the laptop's agent ended AMCL and AR when their 3 s leases ran out."""
import socket

import pytest
import rosgraph
import rospy
import rospy.impl.tcpros_service as tcpros_service

from anyscale_core.agent_client import AgentClient

URI = "rosrpc://laptop:41000"


class Connected(Exception):
    """Where the call connected: the test's stand-in for a service's answer."""


class FakeTransport:
    def __init__(self, protocol, name):
        pass

    def connect(self, host, port, uri):
        raise Connected(uri)


class FakeMaster:
    """lookupService as rosmaster answers it: `state` is "up" (the URI), "down" (refused) or
    "restarted" (unknown service)."""
    state = "up"
    uri = URI

    def __init__(self, caller_id):
        pass

    def lookupService(self, service):
        if FakeMaster.state == "down":
            raise socket.error("connection refused")
        if FakeMaster.state == "restarted":
            raise rosgraph.MasterError(f"no provider for {service}")
        return FakeMaster.uri


@pytest.fixture
def master(monkeypatch):
    monkeypatch.setattr(tcpros_service.rosgraph, "Master", FakeMaster)
    monkeypatch.setattr(tcpros_service, "TCPROSTransport", FakeTransport)
    FakeMaster.state, FakeMaster.uri = "up", URI
    return FakeMaster


def called(client):
    """The URI a lease renewal on the laptop connected to."""
    with pytest.raises(Connected) as where:
        client.renew("laptop", ["amcl"], 3.0)
    return str(where.value)


@pytest.mark.parametrize("state", ["down", "restarted"])
def test_a_service_found_once_is_called_while_the_master_cannot_tell_where_it_is(master, state):
    client = AgentClient(1.0, 1.0)
    assert called(client) == URI
    master.state = state
    assert called(client) == URI


def test_the_masters_answer_wins_when_it_has_one(master):
    client = AgentClient(1.0, 1.0)
    called(client)
    master.uri = "rosrpc://laptop:42000"        # the agent was restarted: a new port
    assert called(client) == "rosrpc://laptop:42000"
    master.state = "restarted"
    assert called(client) == "rosrpc://laptop:42000"


def test_a_service_never_found_is_still_an_error(master):
    master.state = "restarted"
    with pytest.raises(rospy.ServiceException):
        AgentClient(1.0, 1.0).renew("laptop", ["amcl"], 3.0)
