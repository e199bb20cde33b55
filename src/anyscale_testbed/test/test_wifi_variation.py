"""The seeded WiFi variation: shadowing along the path and interference episodes; seed 0 is the
deterministic model."""
import math

import numpy as np
import pytest

from anyscale_testbed.wifi_link_model import CoverageModel, usable_bandwidth_mbps
from anyscale_testbed.wifi_variation import (STEP_M, Episode, InterferenceParams,
                                             ShadowingParams, ShadowingSequence,
                                             TravelledDistance, VariedCoverage,
                                             interference_at, interference_episodes)


def floor_with_wall():
    grid = np.zeros((40, 80), dtype=bool)   # 0.5 m cells: 40 m x 20 m
    grid[:, 30] = True                      # a wall at x = 15.0..15.5 m
    return CoverageModel(grid, 0.5, (0.0, 0.0), access_point_xy=(2.0, 10.0))


def path_along_floor(n=400):
    """(x, y, travelled, t): the robot driving east at 0.4 m/s, through the wall's doorway."""
    xs = np.linspace(1.0, 39.0, n)
    travelled = xs - xs[0]
    return [(x, 10.0 + 3.0 * math.sin(x / 4.0), d, d / 0.4) for x, d in zip(xs, travelled)]


def bandwidths(seed, path):
    varied = VariedCoverage(floor_with_wall(), seed)
    return [varied.bandwidth_at(x, y, d, t) for x, y, d, t in path]


def test_seed_zero_is_the_deterministic_model():
    model, path = floor_with_wall(), path_along_floor()
    assert bandwidths(0, path) == [model.bandwidth_at(x, y) for x, y, _, _ in path]
    assert VariedCoverage(model, 0).episodes == []


def test_a_seed_gives_the_same_link_every_time_and_seeds_differ():
    path = path_along_floor()
    one = bandwidths(1, path)
    assert one == bandwidths(1, path)
    # Queried in another order (the shaper's ticks vary), a place still gets the same value.
    varied = VariedCoverage(floor_with_wall(), 1)
    backwards = [varied.bandwidth_at(x, y, d, t) for x, y, d, t in reversed(path)]
    assert backwards[::-1] == one
    two, three = bandwidths(2, path), bandwidths(3, path)
    assert one != two and two != three and one != three
    plain = bandwidths(0, path)
    assert one != plain


@pytest.mark.parametrize("decorrelation_m", [6.0, 10.0])
def test_shadowing_sequence_is_unit_variance_with_exponential_correlation(decorrelation_m):
    lag = int(round(decorrelation_m / STEP_M))
    values, correlations = [], []
    for seed in range(1, 11):
        sequence = ShadowingSequence(seed, 1, decorrelation_m)
        z = np.array([sequence.at(k * STEP_M) for k in range(20000)])     # 2 km each
        values.append(z)
        correlations.append(np.corrcoef(z[:-lag], z[lag:])[0, 1])
    z = np.concatenate(values)
    assert abs(z.mean()) < 0.1
    assert z.std() == pytest.approx(1.0, abs=0.1)
    assert np.mean(correlations) == pytest.approx(math.exp(-1.0), abs=0.08)


def test_shadowing_in_db_has_the_38901_sigma_with_and_without_line_of_sight():
    params = ShadowingParams()
    los, nlos = [], []
    for seed in range(1, 11):
        varied = VariedCoverage(floor_with_wall(), seed)
        los += [varied.shadowing_db(d, True) for d in np.arange(0.0, 1000.0, 1.0)]
        nlos += [varied.shadowing_db(d, False) for d in np.arange(0.0, 1000.0, 1.0)]
    assert np.std(los) == pytest.approx(params.los_sigma_db, rel=0.12)
    assert np.std(nlos) == pytest.approx(params.nlos_sigma_db, rel=0.12)
    # Independent processes: not the same sequence scaled.
    assert abs(np.corrcoef(los, nlos)[0, 1]) < 0.1


def test_interference_episodes_follow_the_stated_rates():
    params = InterferenceParams()
    episodes = interference_episodes(7, 100 * 3600.0, params)          # 100 h
    per_min = len(episodes) / (100 * 60.0)
    assert per_min == pytest.approx(params.episodes_per_min, rel=0.05)
    durations = [e.end_s - e.start_s for e in episodes]
    assert np.mean(durations) == pytest.approx(params.mean_duration_s, rel=0.05)
    drops = [e.drops_link for e in episodes]
    assert np.mean(drops) == pytest.approx(params.drop_share, abs=0.03)
    assert all(e.penalty_db == (0.0 if e.drops_link else params.penalty_db) for e in episodes)
    assert [e.start_s for e in episodes] == sorted(e.start_s for e in episodes)
    assert interference_episodes(7, 3600.0, params) == [e for e in episodes if e.start_s < 3600]
    assert interference_episodes(0, 3600.0, params) == []


def test_a_drop_wins_and_overlapping_penalties_take_the_worst():
    episodes = [Episode(10.0, 20.0, False, 10.0), Episode(15.0, 30.0, False, 6.0),
                Episode(25.0, 27.0, True, 0.0)]
    assert interference_at(episodes, 5.0) == (False, 0.0)
    assert interference_at(episodes, 16.0) == (False, 10.0)
    assert interference_at(episodes, 22.0) == (False, 6.0)
    assert interference_at(episodes, 26.0) == (True, 6.0)
    assert interference_at(episodes, 30.0) == (False, 0.0)


def test_an_episode_cuts_the_rate_or_drops_the_link_where_it_happens():
    model = floor_with_wall()
    varied = VariedCoverage(model, 5)
    in_drop = next(e.start_s for e in varied.episodes if e.drops_link)
    in_penalty = next(e.start_s for e in varied.episodes
                      if not e.drops_link and not interference_at(varied.episodes, e.start_s)[0])
    quiet = next(t for t in np.arange(0.0, 600.0, 0.5)
                 if interference_at(varied.episodes, t) == (False, 0.0))
    penalty = interference_at(varied.episodes, in_penalty)[1]
    assert penalty == InterferenceParams().penalty_db
    lowered = 0
    for x, y, d, _ in path_along_floor():
        rx, walls = model.received_power_at(x, y)
        shadowed = rx + varied.shadowing_db(d, walls == 0)
        assert varied.bandwidth_at(x, y, d, in_drop) == 0.0
        assert varied.bandwidth_at(x, y, d, quiet) == usable_bandwidth_mbps(shadowed)
        cut = varied.bandwidth_at(x, y, d, in_penalty)
        assert cut == usable_bandwidth_mbps(shadowed - penalty)
        lowered += cut < varied.bandwidth_at(x, y, d, quiet)
    assert lowered > 0          # somewhere on the path the lost margin costs a rate step


def test_bad_seeds_are_refused():
    for bad in (-1, 1.5, True, "3"):
        with pytest.raises(ValueError, match="seed must be an integer >= 0"):
            VariedCoverage(floor_with_wall(), bad)


def test_travelled_distance_adds_the_steps():
    travelled = TravelledDistance()
    assert travelled.update(0.0, 0.0) == 0.0
    assert travelled.update(3.0, 4.0) == 5.0
    assert travelled.update(3.0, 4.0) == 5.0
    assert travelled.update(3.0, 0.0) == 9.0
