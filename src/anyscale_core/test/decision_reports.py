"""The decision engine's tests on the test bed (test_decision_engine_*.py) share these: agent
reports made up for a moment, every Table I topic healthy unless told otherwise, the paper's
decision parameters and which nodes run away from the robot. Their `engine` fixture is in
conftest.py."""
from anyscale_core.decision_types import DecisionParams, ScaleReport

# Every Table I topic at its optimal rate.
HEALTHY = {"/scan": 10.0, "/joint_states": 40.0, "/wheel_ticks": 40.0,
           "/camera/image_raw": 30.0, "/amcl_pose": 5.0, "/odom": 10.0,
           "/odometry/filtered": 5.0, "/ar_markers": 30.0}


# The paper's decisions: a move out judged on the bandwidth of the moment (no hold).
PAPER = DecisionParams(bandwidth_hold_s=0.0)


def reports(now, bandwidth=20.0, laptop=True, rates=None, laptop_running=(), laptop_load=0.0,
            silence=None):
    """scale -> its report received at `now`: the robot's, and the laptop's unless not `laptop`
    (its link up with `bandwidth` Mbit/s, `laptop_running` its model nodes). Every topic was
    last received 0.01 s before, unless `silence` (topic -> s) says otherwise."""
    rates = {**HEALTHY, **(rates or {})}
    quiet = {**{t: 0.01 for t in HEALTHY}, **(silence or {})}
    out = {"robot": ScaleReport("robot", now, 40.0, 2.0, {}, rates, topic_silence=quiet)}
    if laptop:
        out["laptop"] = ScaleReport("laptop", now, laptop_load, 4.0,
                                    {n: 10.0 for n in laptop_running}, rates, True, bandwidth,
                                    topic_silence=quiet)
    return out


def remote(engine):
    """The nodes the engine has mapped away from the robot, sorted."""
    return sorted(n for n, s in engine.mapping().items() if s != "robot")
