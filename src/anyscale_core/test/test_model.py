"""Loading and validating system models: the test bed loads; each kind of bad model is refused
with an error naming the file, the key and what was expected."""
import pytest

from anyscale_core.model import ModelError
from anyscale_core.model_loader import load_model, parse_model

from core_test_data import DELETE, mutated


def test_testbed_loads(testbed):
    assert testbed.master.name == "robot"
    assert [s.name for s in testbed.remote_scales] == ["laptop"]
    assert len(testbed.nodes) == 11
    assert len(testbed.connections) == 8
    amcl = testbed.node("amcl")
    assert amcl.launch.package == "paper_app"
    assert amcl.state_handoff.kind == "pose"
    assert amcl.launch.warm_start and not testbed.node("laser").launch.warm_start
    assert amcl.launch.nice == 0 and testbed.node("ar_recognition").launch.nice == 5


BAD_MODELS = [
    # (path to change, new value, key expected in the message, words expected)
    (("scales",), DELETE, "scales", "missing required key"),
    (("scales", 0, "master"), False, "scales", "no scale has master"),
    (("scales", 1, "master"), True, "scales", "more than one master"),
    (("scales", 1, "name"), "robot", "scales[1].name", "duplicate scale name"),
    (("scales", 0, "cpu_ghz"), -1, "scales[0].cpu_ghz", "> 0"),
    (("scales", 0, "cores"), 1.5, "scales[0].cores", "integer"),
    (("network", "max_bandwidth_mbps"), "fast", "network.max_bandwidth_mbps", "number"),
    (("nodes", 1, "name"), "laser", "nodes[1].name", "duplicate node name"),
    (("nodes", 1, "name"), "bad name", "nodes[1].name", "ROS node name"),
    # `$` matched before a trailing newline: the CLI took a name the agent refuses.
    (("nodes", 1, "name"), "laser\n", "nodes[1].name", "ROS node name"),
    (("nodes", 9, "launch", "package"), "anyscale_nav_demo\n", "launch.package", "package name"),
    (("nodes", 9, "name"), "amcl__laptop", "nodes[9].name", "reserved for the names instances"),
    (("nodes", 9, "cpu_usage", "robot"), 150, "nodes[9] (amcl).cpu_usage.robot", "<= 100"),
    (("nodes", 9, "cpu_usage", "robot"), -5, "nodes[9] (amcl).cpu_usage.robot", ">= 0"),
    (("nodes", 9, "cpu_usage", "server"), 10, "nodes[9] (amcl).cpu_usage.server",
     "unknown scale 'server'"),
    (("nodes", 9, "launch"), DELETE, "nodes[9] (amcl).launch", "package and launch.type"),
    (("nodes", 9, "launch", "type"), DELETE, "nodes[9] (amcl).launch.type", "missing"),
    (("nodes", 9, "launch", "type"), "../../bin/sh", "nodes[9] (amcl).launch.type", "no path"),
    (("nodes", 9, "launch", "package"), DELETE, "nodes[9] (amcl).launch.package", "missing"),
    (("nodes", 9, "pinned"), "server", "nodes[9] (amcl).pinned", "unknown scale"),
    (("nodes", 9, "launch", "warm_start"), "yes", "nodes[9] (amcl).launch.warm_start",
     "true or false"),
    (("nodes", 9, "launch", "nice"), 20, "nodes[9] (amcl).launch.nice", "-20 to 19"),
    (("nodes", 9, "launch", "nice"), -21, "nodes[9] (amcl).launch.nice", "from -20 to 19"),
    (("nodes", 9, "launch", "nice"), "high", "nodes[9] (amcl).launch.nice", "integer"),
    (("nodes", 9, "cpu_usage"), {"laptop": 10}, "nodes[9] (amcl).cpu_usage", "'robot'"),
    (("nodes", 9, "state_handoff", "kind"), "memory", "state_handoff.kind", "pose"),
    (("nodes", 9, "colour"), "green", "nodes[9] (amcl).colour", "unknown key"),
    (("nodes", 8, "pinned"), "laptop", "nodes[8] (navigation).pinned", "critical node"),
    (("connections", 0, "publisher"), "lidar", "connections[0].publisher", "unknown node 'lidar'"),
    (("connections", 0, "subscriber"), "nobody", "connections[0].subscriber", "unknown node"),
    (("connections", 0, "freq_min"), 0, "connections[0].freq_min", "> 0"),
    (("connections", 0, "freq_min"), -2, "connections[0].freq_min", "> 0"),
    (("connections", 0, "freq_opt"), 1, "connections[0].freq_opt", "freq_opt >= freq_min"),
    (("connections", 0, "tolerance"), -1, "connections[0].tolerance", ">= 0"),
    (("connections", 0, "tolerance"), DELETE, "connections[0].tolerance", "missing"),
    (("connections", 1), {"publisher": "laser", "subscriber": "amcl", "topic": "/scan",
                          "freq_min": 5, "freq_opt": 10, "tolerance": 2},
     "connections[1]", "duplicate connection"),
    (("scales", 0, "memory_mb"), 100, "nodes", "need"),
]


@pytest.mark.parametrize("path,value,key,words", BAD_MODELS,
                         ids=[f"{'.'.join(map(str, b[0]))}" for b in BAD_MODELS])
def test_bad_model_names_file_key_and_expectation(testbed_dict, path, value, key, words):
    with pytest.raises(ModelError) as err:
        parse_model(mutated(testbed_dict, path, value), "bad.yaml")
    message = str(err.value)
    assert message.startswith("bad.yaml: ")
    assert key in message
    assert words in message


def test_yaml_syntax_error_names_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("scales:\n  - name: robot\n    master: [true\n")
    with pytest.raises(ModelError) as err:
        load_model(str(path))
    assert str(path) in str(err.value)
    assert "invalid YAML: line" in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(ModelError, match="cannot read"):
        load_model(str(tmp_path / "absent.yaml"))


def test_not_a_mapping():
    with pytest.raises(ModelError, match="expected a mapping, got list"):
        parse_model([1, 2], "list.yaml")


def test_instance_names_and_output_topics(testbed_dict):
    model = parse_model(testbed_dict, "testbed.yaml")
    assert model.instance_name("amcl", "robot") == "/amcl"
    assert model.instance_name("amcl", "laptop") == "/amcl__laptop"
    assert model.output_topics("amcl") == ("/amcl_pose",)
    assert model.output_topics("laser") == ("/scan",)      # two connections, one topic
    assert model.output_topics("navigation") == ()
