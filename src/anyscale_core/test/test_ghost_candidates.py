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
