"""`anyscale model draft` without ROS: model_draft.py on inline graph snapshots (odd names,
nodes without connections, /rosout and AnyScale's own nodes left out, nodes on another
machine), drafts whose TODOs are filled and then pass `anyscale check` and `plan`, and the
command never overwriting a file."""
import json

import pytest
import yaml

from anyscale_core.cli import main
from anyscale_core.model_draft import (TODO, GraphSnapshot, Machine, NodeInfo, Rate,
                                       application_nodes, decimal, draft_model, executable_index,
                                       graph_connections, launch_args, model_names,
                                       package_of_executable)
from anyscale_core.model_loader import parse_model

from core_test_data import filled_draft

TALKER_CMD = ("/usr/bin/python3", "/usr/bin/rostopic", "pub", "-r", "10", "/chatter",
              "std_msgs/String", "data: hi", "__name:=talker", "__log:=/tmp/talker.log")
RELAY_CMD = ("/usr/lib/topic_tools/relay", "/chatter", "/chatter_relay", "__name:=relay")
LISTENER_CMD = ("/usr/bin/python3", "-u", "/ws/src/my_pkg/scripts/listen.py",
                "chatter:=/chatter_relay", "_rate:=2.5", "_frame:=base_link", "__ns:=/ns",
                "__name:=listener")


def snapshot(**changes) -> GraphSnapshot:
    """A small graph: talker -> relay -> /ns/listener, a latched /map to the listener, a node
    on another machine, a node without connections, /rosout, an AnyScale agent and the
    drafting command's own subscriber."""
    nodes = {
        "/talker": NodeInfo("/talker", "localhost", 11, TALKER_CMD, "rostopic", "rostopic", 40.2),
        "/relay": NodeInfo("/relay", "localhost", 12, RELAY_CMD, "topic_tools", "relay", 9.6),
        "/ns/listener": NodeInfo("/ns/listener", "localhost", 13, LISTENER_CMD, "my_pkg",
                                 "listen.py", 41.0),
        "/map_server": NodeInfo("/map_server", "robot-pc", 14),
        "/remote_viz": NodeInfo("/remote_viz", "laptop.local"),
        "/my__node": NodeInfo("/my__node", "localhost", 15, ("/opt/bin/tool",), None, None, 1.0),
        "/rosout": NodeInfo("/rosout", "localhost", 16, ("/usr/lib/rosout/rosout",), "rosout",
                            "rosout", 5.0),
        "/anyscale_agent_robot": NodeInfo("/anyscale_agent_robot"),
        "/anyscale_model_draft_77_1": NodeInfo("/anyscale_model_draft_77_1"),
    }
    data = dict(
        publishers={"/chatter": ["/talker"], "/chatter_relay": ["/relay"],
                    "/map": ["/map_server"], "/rosout": ["/talker", "/relay", "/my__node"],
                    "/rosout_agg": ["/rosout"], "/anyscale/status": ["/anyscale_agent_robot"],
                    "/viz": ["/relay"]},
        subscribers={"/chatter": ["/relay", "/anyscale_model_draft_77_1"],
                     "/chatter_relay": ["/ns/listener", "/remote_viz"],
                     "/map": ["/ns/listener"], "/rosout": ["/rosout"],
                     "/unpublished": ["/ns/listener"]},
        types={"/chatter": "std_msgs/String", "/chatter_relay": "std_msgs/String",
               "/map": "nav_msgs/OccupancyGrid"},
        nodes=nodes,
        rates={("/chatter", "/talker"): Rate(9.96, 1250.0),
               ("/chatter_relay", "/relay"): Rate(9.96, 1250.0)},
        seconds=5.0, master_uri="http://localhost:11311",
        machine=Machine(cores=2, cpu_ghz=2.6, memory_mb=24106))
    data.update(changes)
    return GraphSnapshot(**data)


def drafted(snap=None) -> dict:
    return yaml.safe_load(draft_model(snap or snapshot()))


def node_entry(model: dict, name: str) -> dict:
    return next(n for n in model["nodes"] if n["name"] == name)


def test_rosout_anyscale_and_the_drafter_are_left_out():
    snap = snapshot()
    assert application_nodes(snap) == ["/map_server", "/my__node", "/ns/listener", "/relay",
                                       "/remote_viz", "/talker"]
    topics = {c.topic for c in graph_connections(snap, application_nodes(snap))}
    assert topics == {"/chatter", "/chatter_relay", "/map"}
    text = draft_model(snap)
    assert "rosout" not in text.replace("Left out: /rosout", "")
    assert "anyscale_agent" not in text and "anyscale_model_draft_" not in text


def test_every_connection_with_its_measured_rate_and_bandwidth():
    connections = drafted()["connections"]
    assert [(c["publisher"], c["subscriber"], c["topic"]) for c in connections] == [
        ("talker", "relay", "/chatter"), ("relay", "ns_listener", "/chatter_relay"),
        ("relay", "remote_viz", "/chatter_relay"), ("map_server", "ns_listener", "/map")]
    first = connections[0]
    assert first["freq_opt"] == 10.0 and first["bandwidth_mbps"] == 0.01
    assert first["freq_min"] == TODO and first["tolerance"] == TODO
    # The latched map sent no message in the window: a human decides its rate.
    assert connections[3]["freq_opt"] == TODO and connections[3]["bandwidth_mbps"] == 0


def test_nodes_keep_package_type_args_remaps_and_params():
    model = drafted()
    talker = node_entry(model, "talker")
    assert talker["launch"] == {"package": "rostopic", "type": "rostopic",
                                "args": ["pub", "-r", "10", "/chatter", "std_msgs/String",
                                         "data: hi"]}
    assert talker["memory_mb"] == 40 and talker["pinned"] == TODO   # publishes only
    listener = node_entry(model, "ns_listener")
    assert listener["launch"] == {"package": "my_pkg", "type": "listen.py",
                                  "remaps": {"chatter": "/chatter_relay"},
                                  "params": {"rate": 2.5, "frame": "base_link"}}
    assert "pinned" not in listener and "pinned" not in node_entry(model, "relay")
    assert listener["cpu_usage"] == {"robot": TODO, "laptop": TODO}


def test_nodes_elsewhere_or_unresolved_get_todos():
    model = drafted()
    assert node_entry(model, "remote_viz")["launch"] == {"package": TODO, "type": TODO}
    assert node_entry(model, "remote_viz")["memory_mb"] == TODO
    assert node_entry(model, "map_server")["launch"] == {"package": TODO, "type": TODO}
    assert node_entry(model, "my_node")["launch"] == {"package": TODO, "type": TODO}
    text = draft_model(snapshot())
    assert "runs on laptop.local" in text and "no package installs /opt/bin/tool" in text


def test_a_node_without_connections_is_drafted_and_says_so():
    text = draft_model(snapshot())
    block = text[text.index("- name: my_node"):text.index("- name: ns_listener")]
    assert "ROS name /my__node; AnyScale starts it as /my_node" in block
    assert "no connection to another node" in block


def test_odd_names_become_unique_model_names():
    assert model_names(["/ns/cam", "/ns_cam", "/my__node", "/a/b__c/d", "/9lives",
                        "/amcl__laptop"]) == {
        "/9lives": "node_9lives", "/a/b__c/d": "a_b_c_d", "/amcl__laptop": "amcl_laptop",
        "/my__node": "my_node", "/ns/cam": "ns_cam", "/ns_cam": "ns_cam_2"}


def test_master_elsewhere_leaves_its_figures_to_fill():
    model = drafted(snapshot(machine=None))
    assert model["scales"][0]["master"] is True and model["scales"][0]["cores"] == TODO
    assert drafted()["scales"][0]["cores"] == 2


def test_an_empty_graph_drafts_no_connections():
    snap = snapshot(publishers={"/rosout_agg": ["/rosout"]}, subscribers={}, rates={},
                    nodes={"/rosout": NodeInfo("/rosout"), "/lonely": NodeInfo("/lonely")})
    model = drafted(snap)
    assert model["connections"] == [] and [n["name"] for n in model["nodes"]] == ["lonely"]


@pytest.mark.parametrize("cmdline, index", [
    (RELAY_CMD, 0), (TALKER_CMD, 1), (LISTENER_CMD, 2), (("python3", "-u"), 0), ((), 0)])
def test_executable_index(cmdline, index):
    assert executable_index(cmdline) == index


def test_launch_args_drop_roslaunch_specials():
    spec = launch_args(LISTENER_CMD)
    assert spec.args == ()
    assert spec.remaps == (("chatter", "/chatter_relay"),)
    assert launch_args(("/bin/x", "a:=b:=c", "--flag", "x=1")).remaps == (("a", "b:=c"),)
    assert launch_args(("/bin/x", "a:=b:=c", "--flag", "x=1")).args == ("--flag", "x=1")


def test_package_of_executable():
    dirs = {"my_pkg": "/ws/src/my_pkg", "my_pkg_extra": "/ws/src/my_pkg/extra",
            "topic_tools": "/usr/share/topic_tools", "rostopic": "/usr/share/rostopic"}
    owners = {"rostopic": ["rostopic"], "relay": ["topic_tools"], "twice": ["a", "b"]}
    assert package_of_executable("/ws/src/my_pkg/scripts/listen.py", dirs, owners) == \
        ("my_pkg", "listen.py")
    assert package_of_executable("/ws/src/my_pkg/extra/x", dirs, owners) == ("my_pkg_extra", "x")
    assert package_of_executable("/ws/devel/lib/topic_tools/relay", dirs, owners) == \
        ("topic_tools", "relay")
    assert package_of_executable("/usr/bin/rostopic", dirs, owners) == ("rostopic", "rostopic")
    assert package_of_executable("/usr/bin/twice", dirs, owners) is None
    assert package_of_executable("/ws/src/my_pkgX/y", dirs, owners) is None


def test_numbers_stay_numbers_in_yaml():
    assert yaml.safe_load(decimal(0.0000123)) == 0.0000123
    assert decimal(0.0) == "0" and decimal(10.0) == "10"


def test_the_draft_is_refused_until_its_todos_are_filled():
    with pytest.raises(ValueError, match="expected a finite number, got str 'TODO'"):
        parse_model(drafted())


def test_a_filled_draft_passes_check_and_plan(tmp_path, capsys):
    path = tmp_path / "drafted.yaml"
    path.write_text(yaml.safe_dump(filled_draft(drafted(), critical_topics={"/map"})))
    assert "TODO" not in path.read_text()
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "critical nodes (2, pinned to robot): map_server, ns_listener" in out
    assert main(["plan", str(path), "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    assert plan["feasible"] is True and plan["mapping"]["ns_listener"] == "robot"
    assert set(plan["mapping"]) == {"talker", "relay", "ns_listener", "map_server",
                                    "remote_viz", "my_node"}


def test_filling_the_text_in_place_keeps_the_comments_valid(tmp_path, capsys):
    # A user edits the text: the comments and layout of the draft must survive as YAML.
    text = draft_model(snapshot())
    for key, value in (("cpu_ghz: TODO", "cpu_ghz: 2.8"), ("cores: TODO", "cores: 4"),
                       ("memory_mb: TODO", "memory_mb: 4096"), ("alpha: TODO", "alpha: 3.5"),
                       ("technology: TODO", "technology: wifi"),
                       ("max_bandwidth_mbps: TODO", "max_bandwidth_mbps: 54"),
                       ("package: TODO", "package: my_pkg"), ("type: TODO", "type: tool"),
                       ("pinned: TODO", "pinned: robot"), (": TODO", ": 1")):
        text = text.replace(key, value)
    path = tmp_path / "edited.yaml"
    path.write_text(text)
    assert main(["check", str(path)]) == 0, capsys.readouterr().err


def test_draft_never_overwrites_without_force(tmp_path, capsys, monkeypatch):
    existing = tmp_path / "mine.yaml"
    existing.write_text("# the user's own values\n")
    collected = []
    monkeypatch.setattr("anyscale_core.model_draft_ros.collect_snapshot",
                        lambda seconds: collected.append(seconds) or snapshot())
    assert main(["model", "draft", str(existing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"anyscale model draft: error: {existing}: exists; give --force to "
                   "overwrite it"]
    assert existing.read_text() == "# the user's own values\n" and collected == []
    assert main(["model", "draft", str(existing), "--force", "--seconds", "2"]) == 0
    assert collected == [2.0] and "talker" in existing.read_text()


def test_draft_refuses_a_file_that_appears_while_counting(tmp_path, capsys, monkeypatch):
    late = tmp_path / "late.yaml"

    def collect(seconds):
        late.write_text("# written meanwhile\n")
        return snapshot()
    monkeypatch.setattr("anyscale_core.model_draft_ros.collect_snapshot", collect)
    assert main(["model", "draft", str(late)]) == 2
    assert "exists; give --force" in capsys.readouterr().err
    assert late.read_text() == "# written meanwhile\n"


@pytest.mark.parametrize("seconds", ["0", "-1", "nan", "4000"])
def test_bad_seconds_exit_2_with_one_line(tmp_path, capsys, seconds):
    assert main(["model", "draft", str(tmp_path / "m.yaml"), "--seconds", seconds]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("anyscale model draft: error: --seconds:")


def test_help_has_an_example(capsys):
    with pytest.raises(SystemExit) as done:
        main(["model", "draft", "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: anyscale model draft")
    assert "anyscale model draft my_robot.yaml --seconds 10" in out
