"""The mission's route ahead: the plan to the current goal, then the legs through the goals after
it, as far as a length; each goal planned once."""
import numpy as np

from anyscale_nav_demo import costmap as cm
from anyscale_nav_demo.mission_route import MissionRoute

RES = 0.1


def open_room():
    occ = np.zeros((60, 100), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return occ


class CountingPlanner:
    """A planner factory on a 10 m x 6 m room that counts the planners it makes."""

    def __init__(self, occ):
        self.cost = cm.inflate(occ, np.zeros_like(occ), RES, 0.3, 0.8, 3.0)
        self.graph = cm.grid_graph(self.cost, RES, 0.0)
        self.made = []

    def __call__(self, goal_xy):
        self.made.append(goal_xy)
        try:
            return cm.NavigationFunction(self.cost, RES, (0.0, 0.0), self.graph, goal_xy)
        except ValueError:
            return None


def length(points):
    return float(np.hypot(*np.diff(points, axis=0).T).sum())


GOALS = [(2.0, 3.0, 0.0, 0), (8.0, 3.0, 0.0, 1), (8.0, 1.0, 0.0, 2), (2.0, 1.0, 0.0, -1)]


def test_the_route_runs_on_past_the_current_goal_through_the_next_ones():
    plan = CountingPlanner(open_room())
    route = MissionRoute(GOALS, plan)
    to_goal_0 = route.planner(GOALS[0]).path_from((1.0, 3.0))
    ahead = route.ahead(to_goal_0, 0, 100.0)
    # 1 m to goal 0, then 6 m, 2 m and 6 m of legs (grid paths: a little longer)
    assert 15.0 <= length(ahead) < 17.0
    assert np.hypot(*(ahead[-1] - GOALS[-1][:2])) < 0.2
    for goal in GOALS[1:]:
        assert np.min(np.hypot(*(ahead - goal[:2]).T)) < 0.2, goal


def test_the_route_stops_once_it_is_long_enough():
    route = MissionRoute(GOALS, CountingPlanner(open_room()))
    ahead = route.ahead(route.planner(GOALS[0]).path_from((1.0, 3.0)), 0, 5.0)
    # the plan to goal 0 (1 m) is not enough, the first leg (6 m) is: goal 2 is not on it
    assert 6.5 <= length(ahead) < 8.0
    assert np.min(np.hypot(*(ahead - GOALS[2][:2]).T)) > 1.0


def test_from_the_last_goal_the_route_is_the_plan_alone():
    route = MissionRoute(GOALS, CountingPlanner(open_room()))
    to_last = route.planner(GOALS[3]).path_from((3.0, 1.0))
    assert np.array_equal(route.ahead(to_last, 3, 100.0), to_last)


def test_a_goal_visited_on_every_lap_is_planned_once():
    plan = CountingPlanner(open_room())
    route = MissionRoute(GOALS * 3, plan)
    route.ahead(np.array([[1.0, 3.0], [2.0, 3.0]]), 0, 1000.0)
    assert sorted(plan.made) == sorted((g[0], g[1]) for g in GOALS)


def test_a_leg_that_cannot_be_planned_ends_the_route_there():
    occ = open_room()
    occ[:, 50] = True                          # a wall across the room: x >= 5 m unreachable
    route = MissionRoute([(2.0, 3.0, 0, 0), (8.0, 3.0, 0, 1), (2.0, 1.0, 0, -1)],
                         CountingPlanner(occ))
    to_goal_0 = np.array([[1.0, 3.0], [2.0, 3.0]])
    assert np.array_equal(route.ahead(to_goal_0, 0, 100.0), to_goal_0)


def test_no_plan_to_the_current_goal_is_no_route():
    route = MissionRoute(GOALS, CountingPlanner(open_room()))
    assert route.ahead(None, 0, 10.0) is None
    assert route.ahead(np.zeros((0, 2)), 0, 10.0) is None
