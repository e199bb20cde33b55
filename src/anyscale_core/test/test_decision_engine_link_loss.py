"""The decision engine when a link is lost: a silent laptop (stale status, carrier kept) brings
its nodes back with best-effort stops; a lost uplink carrier brings them back at once and sends
nothing across it."""
import dataclasses

from anyscale_core.decision_types import RenewLeases, StartNode, StopNode

from decision_reports import remote, reports


def test_a_silent_laptop_brings_both_back_and_is_only_sent_best_effort_stops(engine):
    for t in (1.0, 2.0):
        engine.tick(reports(t), t)
    # The laptop's reports stop (stale after status_timeout_s); the robot's uplink keeps its
    # carrier: the link may be saturated rather than gone.
    stale = reports(2.0)
    result = engine.tick({**stale, "robot": reports(4.0)["robot"]}, 4.0)
    assert remote(engine) == []
    assert {a.node for a in result.actions if isinstance(a, StartNode)} == \
        {"amcl", "ar_recognition"}
    assert all(a.scale == "robot" for a in result.actions if isinstance(a, StartNode))
    stops = [a for a in result.actions if isinstance(a, StopNode)]
    assert {(a.node, a.scale, a.best_effort) for a in stops} == \
        {("amcl", "laptop", True), ("ar_recognition", "laptop", True)}
    assert not any(isinstance(a, RenewLeases) for a in result.actions)


def test_uplink_carrier_loss_on_the_robot_brings_both_back_at_once(engine):
    for t in (1.0, 2.0):
        engine.tick(reports(t), t)
    # The laptop's last report is still fresh, but the robot's uplink has no carrier.
    now = reports(2.1)
    robot = dataclasses.replace(now["robot"], link_up=False)
    result = engine.tick({**now, "robot": robot}, 2.1)
    assert remote(engine) == []
    assert all(a.scale == "robot" for a in result.actions)
    assert {e.reason for e in result.events} == {"link to laptop down"}


def test_a_carrier_loss_return_starts_without_stopping(engine):
    engine.tick(reports(1.0), 1.0)
    now = reports(4.0)
    robot = dataclasses.replace(now["robot"], link_up=False)        # the uplink's carrier
    result = engine.tick({"robot": robot}, 4.0)
    assert not any(isinstance(a, StopNode) for a in result.actions)
