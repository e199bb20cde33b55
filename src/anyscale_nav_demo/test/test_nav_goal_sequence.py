"""Navigation's mission: its status, one line per change, not one per control step; a loop
started at any of its goals."""
import pytest

from anyscale_nav_demo.goal_sequence import DONE, GoalSequence, loop_from_goal


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


def test_a_loop_started_at_a_goal_still_visits_every_goal_and_ends_there():
    goals = [(1.0, 0.0, 0.5, 0), (2.0, 1.0, 1.0, 1), (0.0, 0.0, 0.0, -1)]
    assert loop_from_goal(goals, 2) == ((0.0, 0.0, 0.0), goals)     # the world's own start
    start, rotated = loop_from_goal(goals, 0)
    assert start == (1.0, 0.0, 0.5)
    assert rotated == [goals[1], goals[2], goals[0]]
    with pytest.raises(ValueError, match="goal 3: the loop has goals 0-2"):
        loop_from_goal(goals, 3)
