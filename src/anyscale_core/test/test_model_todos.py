"""model_todos.py: a draft's TODOs in numeric fields load with neutral stand-ins for profile and
thresholds; a TODO anywhere else is still the loader's error; connections named on the command
line."""
import pytest
import yaml

from anyscale_core.model import ModelError
from anyscale_core.model_todos import (home_mapping, parse_connection_spec,
                                       parse_model_with_todos)

DRAFT = """
scales:
  - {name: robot, master: true, cpu_ghz: 2.6, cores: 2, memory_mb: 24106, alpha: 1.0}
  - {name: laptop, cpu_ghz: TODO, cores: TODO, memory_mb: TODO, alpha: TODO}
network: {technology: TODO, max_bandwidth_mbps: TODO}
nodes:
  - name: talker
    launch: {package: rostopic, type: rostopic, args: [pub, /chatter]}
    cpu_usage: {robot: TODO, laptop: TODO}
    memory_mb: 53
    pinned: TODO
  - name: relay
    launch: {package: topic_tools, type: relay, args: [/chatter, /out]}
    cpu_usage: {robot: TODO, laptop: TODO}
    memory_mb: TODO
connections:
  - {publisher: talker, subscriber: relay, topic: /chatter, freq_min: TODO, freq_opt: 10,
     tolerance: TODO, bandwidth_mbps: 0.0005}
"""


def test_a_draft_with_todos_loads_and_says_where_they_were():
    loaded = parse_model_with_todos(yaml.safe_load(DRAFT), "draft.yaml")
    model = loaded.model
    assert "nodes.relay.cpu_usage.laptop" in loaded.todos
    assert "connections.talker:relay:/chatter.tolerance" in loaded.todos
    assert "scales.laptop.cores" in loaded.todos and "nodes.talker.pinned" in loaded.todos
    assert "connections.talker:relay:/chatter.freq_opt" not in loaded.todos
    # Unknown tolerance counts as migratable, so both scales get profiled.
    assert model.connections[0].tolerance > 0
    assert model.node("talker").pinned is None
    assert dict(model.node("relay").cpu_usage) == {"robot": 0.0, "laptop": 0.0}
    assert home_mapping(model) == {"talker": "robot", "relay": "robot"}


def test_todo_where_no_number_belongs_is_still_an_error():
    tree = yaml.safe_load(DRAFT)
    tree["nodes"][0]["launch"]["package"] = "TODO"
    with pytest.raises(ModelError, match=r"nodes\[0\] \(talker\).launch.package"):
        parse_model_with_todos(tree, "draft.yaml")
    tree = yaml.safe_load(DRAFT)
    tree["nodes"][1]["cpu_usage"]["laptop"] = "lots"
    with pytest.raises(ModelError, match="cpu_usage.laptop: expected a finite number"):
        parse_model_with_todos(tree, "draft.yaml")


def test_connection_spec(testbed):
    assert parse_connection_spec(testbed, "laser:amcl:/scan") == ("laser", "amcl", "/scan")
    assert parse_connection_spec(testbed, "laser:amcl:scan") == ("laser", "amcl", "/scan")
    with pytest.raises(ModelError, match="--connection: no connection laser:ekf:/scan in .*"
                                         "connections: laser:amcl:/scan, "):
        parse_connection_spec(testbed, "laser:ekf:/scan")
    with pytest.raises(ModelError, match="expected PUBLISHER:SUBSCRIBER:TOPIC"):
        parse_connection_spec(testbed, "laser->amcl")
