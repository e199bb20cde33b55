"""Navigation's mission status: one line per change, not one per control step."""
from anyscale_nav_demo.goal_sequence import DONE, GoalSequence


def test_the_status_is_handed_out_once_per_change():
    seq = GoalSequence([(1.0, 0.0, 0.0, -1), (2.0, 0.0, 0.0, -1)], 0.2, 0.1, 3.0)
    pose, lines = (0.0, 0.0, 0.0), []
    for step, x in enumerate([0.0, 0.5, 1.0, 1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0]):
        seq.step((x,) + pose[1:], float(step))
        line = seq.status_change()
        if line is not None:
            lines.append(line)
    assert seq.state == DONE
    assert lines == ["drive 0/2", "drive 1/2", "done 2/2"]


def test_a_mission_without_goals_reports_done_once():
    seq = GoalSequence([])
    assert [seq.status_change() for _ in range(3)] == ["done 0/0", None, None]
