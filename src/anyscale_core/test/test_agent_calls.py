"""Repeated agent calls that fail are logged once per change of state; a start that broke off
without an answer is asked once more; a planned move's wait for the new instance's output ends
on its first message, on a new decision, or on time."""
import threading
import time

import pytest

from anyscale_core.agent_client import CallFailures
from anyscale_core.handover_ros import ABANDONED, PUBLISHED, TIMED_OUT, wait_for_output


def test_a_failing_call_is_reported_when_it_starts_failing_and_when_it_works_again():
    calls = CallFailures()
    key = ("renew_leases", "laptop")
    assert [calls.failed(key) for _ in range(5)] == [True, False, False, False, False]
    assert calls.failed(("renew_leases", "server"))          # each call and scale on its own
    assert calls.succeeded(key) == 5
    assert calls.succeeded(key) == 0                          # working: nothing to say
    assert calls.failed(key)                                  # failing again: said again


class FakeWatch:
    def __init__(self):
        self.published = threading.Event()


def test_the_wait_ends_when_the_new_instance_publishes():
    watch = FakeWatch()
    threading.Timer(0.2, watch.published.set).start()
    began = time.monotonic()
    assert wait_for_output(watch, 5.0, lambda: True) == PUBLISHED
    assert time.monotonic() - began < 2.0


def test_the_wait_is_abandoned_when_the_node_is_moved_again():
    moved = threading.Event()
    threading.Timer(0.2, moved.set).start()
    assert wait_for_output(FakeWatch(), 5.0, lambda: not moved.is_set()) == ABANDONED


def test_the_wait_times_out_and_keeps_the_old_lease_alive_meanwhile():
    beats = []
    assert wait_for_output(FakeWatch(), 2.2, lambda: True,
                           lambda: beats.append(time.monotonic())) == TIMED_OUT
    assert len(beats) in (2, 3)                    # about once a second


def _client_answering(outcomes):
    """An AgentClient whose service calls give `outcomes` in turn (an exception is raised)."""
    from anyscale_core import agent_client
    client = agent_client.AgentClient(1.0, 1.0)
    calls = []

    def call(scale, service, timeout_s=None, **request):
        calls.append((scale, service, request["node"]))
        outcome = outcomes[len(calls) - 1]
        if isinstance(outcome, Exception):
            raise outcome
        return outcome
    client.call = call
    return client, calls


def test_a_start_that_broke_off_without_an_answer_is_asked_once_more(monkeypatch):
    import rospy
    from anyscale_core import agent_client
    monkeypatch.setattr(agent_client, "START_RETRY_DELAY_S", 0.0)
    broke = rospy.ServiceException("transport error completing service call: unable to receive "
                                   "data from sender")
    client, calls = _client_answering([broke, "answer"])
    assert client.start("robot", "/ekf", [], 0.0) == "answer"
    assert calls == [("robot", "start_node", "/ekf")] * 2
    client, calls = _client_answering([broke, broke])
    with pytest.raises(rospy.ServiceException):
        client.start("robot", "/ekf", [], 0.0)
    assert len(calls) == 2


def test_a_start_that_timed_out_is_not_asked_again():
    client, calls = _client_answering([TimeoutError("no answer within 1 s"), "answer"])
    with pytest.raises(TimeoutError):
        client.start("laptop", "/amcl", [], 3.0)
    assert len(calls) == 1


def test_the_decision_nodes_worker_logs_a_failed_job_as_the_decision_node(monkeypatch):
    """agent_client.Worker is a JobWorker (test_job_worker.py) whose failed jobs are logged
    as "anyscale decision: <error>"; the next job still runs."""
    import rospy
    from anyscale_core import agent_client
    logged, done = [], []
    monkeypatch.setattr(rospy, "logerr", lambda fmt, *args: logged.append(fmt % args))

    def renew():
        raise TimeoutError("no answer within 1 s")
    worker = agent_client.Worker("anyscale_test")
    worker.submit(renew, key="renew")
    worker.submit(lambda: done.append("next"))
    assert worker.close(10.0)
    assert logged == ["anyscale decision: no answer within 1 s"] and done == ["next"]
