"""The decision engine when a move fails: a remote start that fails returns the node, a new
instance that never published leaves it where it was; either way it is held back for T."""
from decision_reports import remote, reports


def test_failed_remote_start_returns_the_node_and_holds_it(engine):
    engine.tick(reports(1.0), 1.0)
    event = engine.action_failed("amcl", "laptop", 1.5)
    assert event.kind == "migrate_back" and remote(engine) == []
    assert [e.node for e in engine.tick(reports(2.0), 2.0).events] == ["ar_recognition"]


def test_a_move_whose_new_instance_never_published_stays_and_is_held(engine):
    engine.tick(reports(1.0), 1.0)                                    # amcl: robot -> laptop
    event = engine.move_failed("amcl", "robot", "laptop", 5.0)
    assert (event.kind, event.from_scale, event.to_scale) == ("migrate_back", "laptop", "robot")
    assert "did not publish" in event.reason and remote(engine) == []
    moves = [(ev.node, ev.to_scale) for t in (6.0, 7.0, 14.9) for ev in engine.tick(
        reports(t), t).events]
    assert ("amcl", "laptop") not in moves                          # held for T = 10 s
    assert engine.move_failed("amcl", "robot", "laptop", 16.0) is None  # moved again: stands
