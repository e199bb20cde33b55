"""The test bed's WiFi link model: path loss, rate steps, walls on a hand-made grid, schedules."""
import numpy as np
import pytest

from anyscale_testbed.wifi_link_model import (CoverageModel, RadioParams, ScriptedSchedule,
                                              phy_rate_mbps, received_power_dbm, walls_crossed)


def test_log_distance_path_loss():
    radio = RadioParams()
    assert received_power_dbm(1.0, 0, radio) == pytest.approx(15 - 40)
    assert received_power_dbm(10.0, 0, radio) == pytest.approx(15 - 40 - 30)
    assert received_power_dbm(10.0, 2, radio) == pytest.approx(15 - 40 - 30 - 10)
    assert received_power_dbm(0.1, 0, radio) == received_power_dbm(1.0, 0, radio)


@pytest.mark.parametrize("rx,rate", [(-40, 54), (-65, 54), (-65.5, 48), (-72, 24), (-81, 9),
                                     (-82, 6), (-82.1, 0), (-120, 0)])
def test_80211g_rate_steps(rx, rate):
    assert phy_rate_mbps(rx) == rate


def _two_walls():
    grid = np.zeros((20, 40), dtype=bool)   # 0.5 m cells: 20 m x 10 m
    grid[:, 10] = True                      # wall at x = 5.0..5.5 m
    grid[:, 25:27] = True                   # thick wall at x = 12.5..13.5 m
    return grid


def test_walls_crossed_counts_separate_walls():
    grid = _two_walls()
    assert walls_crossed(grid, 0.5, (0.0, 0.0), (1.0, 5.0), (3.0, 5.0)) == 0
    assert walls_crossed(grid, 0.5, (0.0, 0.0), (1.0, 5.0), (8.0, 5.0)) == 1
    assert walls_crossed(grid, 0.5, (0.0, 0.0), (1.0, 5.0), (19.0, 5.0)) == 2
    assert walls_crossed(grid, 0.5, (0.0, 0.0), (19.0, 5.0), (1.0, 5.0)) == 2
    # Outside the map counts as free space.
    assert walls_crossed(grid, 0.5, (0.0, 0.0), (-5.0, 5.0), (1.0, 5.0)) == 0


def test_coverage_falls_with_distance_and_walls():
    model = CoverageModel(_two_walls(), 0.5, (0.0, 0.0), access_point_xy=(1.0, 5.0))
    near, behind_one, behind_two = (model.bandwidth_at(4.0, 5.0), model.bandwidth_at(8.0, 5.0),
                                    model.bandwidth_at(19.0, 5.0))
    assert near == 27.0                                   # 54 Mbit/s PHY, half usable
    assert behind_one == 27.0                             # 7 m, one wall: -55 dBm
    assert behind_two == 12.0                             # 18 m, two walls: -72.7 dBm -> 24
    far_away = CoverageModel(_two_walls(), 0.5, (0.0, 0.0), (1.0, 5.0),
                             RadioParams(wall_loss_db=30.0))
    assert far_away.bandwidth_at(19.0, 5.0) == 0.0        # out of coverage


def test_scripted_schedule_steps():
    s = ScriptedSchedule([(0, 20.0), (10, 2.0), (15, 0.0), (20, 20.0)])
    assert [s.bandwidth_at(t) for t in (0, 9.9, 10, 14, 15, 19.9, 25)] == \
        [20, 20, 2, 2, 0, 0, 20]
    assert s.bandwidth_at(-1) == 20.0
    with pytest.raises(ValueError, match="must not decrease"):
        ScriptedSchedule([(5, 1.0), (1, 1.0)])
    with pytest.raises(ValueError, match=">= 0"):
        ScriptedSchedule([(0, -1.0)])
