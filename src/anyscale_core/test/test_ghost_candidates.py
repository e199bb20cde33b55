"""Which instance names the decision node checks for dead registrations: never where a node
runs, nor a node being handed over, nor a paused instance (it does not answer, yet lives)."""
from anyscale_core.ghost_registrations import ghost_candidates


def test_every_instance_but_where_the_node_runs(testbed):
    mapping = {n: "robot" for n in testbed.node_names}
    mapping["amcl"] = "laptop"
    names = ghost_candidates(testbed, mapping, set(), set())
    assert "/amcl" in names and "/amcl__laptop" not in names
    assert "/ekf__laptop" in names and "/ekf" not in names


def test_nodes_handed_over_and_paused_instances_are_left_alone(testbed):
    mapping = {n: "robot" for n in testbed.node_names}
    mapping["amcl"] = mapping["ar_recognition"] = "laptop"
    names = ghost_candidates(testbed, mapping, {"ar_recognition"}, {"/amcl"})
    assert "/amcl" not in names                    # paused: registered, silent, alive
    assert "/ar_recognition" not in names          # being handed over
    assert "/ekf__laptop" in names


def test_a_pause_counts_until_a_status_sampled_after_it_has_come():
    from anyscale_core.ghost_registrations import PAUSE_SETTLED_S, pauses_under_way
    pausing = {"/amcl": ("robot", None), "/ar_recognition": ("robot", 100.0)}
    # The call is under way, or acknowledged at 100 s with no status of the robot since.
    assert pauses_under_way(pausing, {}) == {"/amcl", "/ar_recognition"}
    assert pauses_under_way(pausing, {"robot": 100.5}) == {"/amcl", "/ar_recognition"}
    # A status that left the agent after the pause: its report decides from now on. A paused
    # instance that died meanwhile is then a candidate like any other, a live one is reported.
    assert pauses_under_way(pausing, {"robot": 100.0 + PAUSE_SETTLED_S + 0.1}) == {"/amcl"}
    # A status of another scale says nothing about the robot's instances.
    assert pauses_under_way(pausing, {"laptop": 200.0}) == {"/amcl", "/ar_recognition"}
