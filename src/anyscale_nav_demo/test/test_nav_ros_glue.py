"""Node parameters: the private namespace is read from the master in one call, then checked."""
import pytest

rospy = pytest.importorskip("rospy")
from anyscale_nav_demo import ros_glue  # noqa: E402  (needs rospy)

SERVER = {"/amcl/max_particles": 5000, "/amcl/laser": {"x": 0.2, "y": 0.0},
          "/amcl/odom_frame_id": "odom", "/use_sim_time": False}


@pytest.fixture
def master(monkeypatch):
    """rospy's parameter calls answered from SERVER for a node named /amcl; counts the calls."""
    calls = []

    def get_param(name, default=KeyError):
        full = "/amcl/" + name[1:].lstrip("/") if name.startswith("~") else name
        calls.append(full)
        if full.endswith("/"):
            found = {k[len(full):]: v for k, v in SERVER.items() if k.startswith(full)}
            if found:
                return found
        elif full in SERVER:
            return SERVER[full]
        if default is KeyError:
            raise KeyError(full)
        return default

    monkeypatch.setattr(ros_glue, "_private_params", None)
    monkeypatch.setattr(rospy, "get_param", get_param)
    monkeypatch.setattr(rospy, "resolve_name",
                        lambda n: "/amcl/" + n[1:] if n.startswith("~") else n)
    return calls


def test_private_parameters_come_from_one_read_of_the_namespace(master):
    assert ros_glue.param("~max_particles", 100, int) == 5000
    assert ros_glue.param("~odom_frame_id", "x", str) == "odom"
    assert ros_glue.param("~min_particles", 500, int) == 500          # default
    assert ros_glue.param("~likelihood_cache_dir", "", str) == ""     # empty: no cache
    assert ros_glue.param("~threshold", float("inf"), finite=False) == float("inf")
    assert ros_glue.raw_param("~laser", {}) == {"x": 0.2, "y": 0.0}
    assert ros_glue.param("~laser/x") == 0.2                           # nested name
    assert master == ["/amcl/"]


def test_global_names_are_read_one_by_one(master):
    assert ros_glue.param("/use_sim_time", True, bool) is False
    assert master == ["/use_sim_time"]


def test_missing_required_and_bad_values_name_the_parameter(master):
    with pytest.raises(ros_glue.ParamError, match="/amcl/map_file: required, not set"):
        ros_glue.param("~map_file", kind=str)
    with pytest.raises(ros_glue.ParamError,
                       match="/amcl/max_particles: expected an integer > 10000, got 5000"):
        ros_glue.param("~max_particles", 1, int, minimum=10000, above=True)
    with pytest.raises(ros_glue.ParamError, match="/amcl/laser: expected a number, got"):
        ros_glue.param("~laser", 1.0)
    with pytest.raises(ros_glue.ParamError, match="/amcl/max_particles: expected true or false"):
        ros_glue.flag("~max_particles", True)
