"""The decision engine's pauses (launch.pause_at_home): a node declared so has its master
instance paused when it moves out, a return never pauses anything, and a node not declared so
is stopped as before."""

from anyscale_core.allocators import make_allocator
from anyscale_core.characterisation import characterise
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams, StopNode
from anyscale_core.model_loader import parse_model

from decision_reports import reports


def stops(result):
    return [a for a in result.actions if isinstance(a, StopNode)]


def test_a_move_out_pauses_the_master_instance_and_a_planned_return_stops_the_remote_one(engine):
    out = engine.tick(reports(1.0), 1.0)                              # amcl: robot -> laptop
    assert stops(out) == [StopNode("amcl", "robot", after_output_on="laptop", pause=True)]
    engine.tick(reports(2.0), 2.0)                                    # ar_recognition out
    back = engine.tick(reports(3.0, bandwidth=3.0), 3.0)              # AR home on a weak link
    assert stops(back) == [StopNode("ar_recognition", "laptop", after_output_on="robot")]


def test_a_node_not_declared_pause_at_home_is_stopped(testbed_dict):
    for node in testbed_dict["nodes"]:
        node["launch"].pop("pause_at_home", None)
    ch = characterise(parse_model(testbed_dict))
    engine = DecisionEngine(ch, make_allocator("paper"),
                            DecisionParams(bandwidth_hold_s=0.0, startup_grace_s=0.0))
    engine.adopt_or_start(reports(0.0), 0.0)
    assert stops(engine.tick(reports(1.0), 1.0)) == [
        StopNode("amcl", "robot", after_output_on="laptop")]
