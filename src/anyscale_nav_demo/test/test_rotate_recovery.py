"""Navigation's rotate recovery (rotate_recovery.py): a robot whose every trajectory collides
for stuck_after_s turns a full circle in place, then plans again; after `attempts` turns with no
free trajectory between them it gives up; a free trajectory resets the count."""
import math

from anyscale_nav_demo.rotate_recovery import (FREE, GAVE_UP, TURNING, RecoveryConfig,
                                               RotateRecovery)

CFG = RecoveryConfig(stuck_after_s=3.0, turn_rad=2 * math.pi, attempts=2)


def turn_fully(r, t, step=0.5):
    """Feeds yaws around a full circle, 0.1 s apart; the time at the end."""
    yaw = 0.0
    while r.step(t, None, yaw) == TURNING:
        t += 0.1
        yaw = math.remainder(yaw + step, 2 * math.pi)
    return t


def test_a_short_block_is_left_to_the_planner():
    r = RotateRecovery(CFG)
    assert r.step(0.0, True, 0.0) == FREE
    assert r.step(2.9, True, 0.0) == FREE
    assert r.step(3.0, False, 0.0) == FREE
    assert r.step(5.9, True, 0.0) == FREE          # blocked again: a new window


def test_a_block_for_stuck_after_s_turns_a_full_circle_then_plans_again():
    r = RotateRecovery(CFG)
    r.step(0.0, True, 0.0)
    assert r.step(3.0, True, 0.0) == TURNING
    yaw, t = 0.0, 3.0
    turns = 0
    while True:
        t += 0.1
        yaw = math.remainder(yaw + 0.5, 2 * math.pi)
        if r.step(t, None, yaw) != TURNING:
            break
        turns += 1
    # 2π at 0.5 rad a period: 13 periods, the thirteenth reaching the full circle
    assert turns == 12
    assert r.step(t + 0.1, True, yaw) == FREE       # the planner gets a new window


def test_it_gives_up_after_the_attempts_and_a_free_path_starts_over():
    r = RotateRecovery(CFG)
    t = 0.0
    for _ in range(CFG.attempts):
        r.step(t, True, 0.0)
        assert r.step(t + 3.0, True, 0.0) == TURNING
        t = turn_fully(r, t + 3.0) + 0.1
    r.step(t, True, 0.0)
    assert r.step(t + 3.0, True, 0.0) == GAVE_UP
    assert r.step(t + 4.0, True, 0.0) == GAVE_UP
    assert r.step(t + 5.0, False, 0.0) == FREE      # a free trajectory: back to planning
    r.step(t + 6.0, True, 0.0)
    assert r.step(t + 9.0, True, 0.0) == TURNING    # and the attempts count again


def test_a_turn_counts_the_angle_turned_whichever_way_the_yaw_wraps():
    r = RotateRecovery(RecoveryConfig(stuck_after_s=0.0, turn_rad=1.0, attempts=1))
    assert r.step(0.0, True, 3.0) == TURNING
    assert r.step(0.1, None, -2.9) == TURNING        # 0.38 rad across ±π
    assert r.step(0.2, None, -2.5) == TURNING        # 0.78
    assert r.step(0.3, None, -2.2) == FREE           # 1.08 >= 1.0


def test_a_turn_that_is_not_seen_ends_at_its_timeout():
    r = RotateRecovery(RecoveryConfig(stuck_after_s=0.0, attempts=1, turn_timeout_s=5.0))
    assert r.step(0.0, True, 0.0) == TURNING
    assert r.step(4.9, None, 0.0) == TURNING         # the yaw never changes
    assert r.step(5.0, None, 0.0) == FREE
    assert r.step(5.1, True, 0.0) == GAVE_UP         # it counted as the one attempt
