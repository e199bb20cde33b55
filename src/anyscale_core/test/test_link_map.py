"""The link map (link_map.py): cells and their conservative figure, ageing, and the file: saved
and loaded back, another resolution, and a missing or corrupt file naming what was wrong."""
import os

import pytest
import yaml

from anyscale_core.link_map import (LinkMap, LinkMapError, LinkMapParams, load_link_map)

T0 = 1_800_000_000.0        # wall clock: a map outlives its run


def filled(params=LinkMapParams()):
    m = LinkMap(params)
    for k in range(10):                                  # cell (2, 3): 20..29 Mbit/s
        m.add("laptop", T0 + k, 2.5, 3.5, 20.0 + k, False)
    for k in range(4):                                   # cell (4, 3): lost
        m.add("laptop", T0 + k, 4.2, 3.9, float("nan"), True)
    return m


def test_a_cell_is_known_from_min_observations_with_a_low_quantile():
    m = LinkMap(LinkMapParams(min_observations=3, quantile=0.1))
    m.add("laptop", T0, 2.5, 3.5, 20.0, False)
    m.add("laptop", T0 + 1, 2.6, 3.4, 25.0, False)
    assert m.stats("laptop", (2, 3)) is None             # 2 of 3: unknown
    m.add("laptop", T0 + 2, 2.9, 3.1, 30.0, False)
    s = m.stats("laptop", (2, 3))
    assert (s.low_mbps, s.lost_fraction, s.count) == (20.0, 0.0, 3)
    assert m.stats("laptop", (3, 3)) is None and m.stats("server", (2, 3)) is None


def test_a_loss_counts_as_zero_and_as_lost():
    m = filled()
    for k in range(2):                                   # 2 losses of 12 in (2, 3)
        m.add("laptop", T0 + 20 + k, 2.2, 3.2, 5.0, True)
    s = m.stats("laptop", (2, 3))
    assert s.low_mbps == 0.0 and s.lost_fraction == pytest.approx(2 / 12) and s.count == 12
    lost = m.stats("laptop", (4, 3))
    assert (lost.low_mbps, lost.lost_fraction) == (0.0, 1.0)


def test_a_cell_keeps_its_newest_observations():
    m = LinkMap(LinkMapParams(cell_observations=5, min_observations=1, quantile=0.0))
    for k in range(5):
        m.add("laptop", T0 + k, 0.5, 0.5, 0.0, True)     # an old hole
    for k in range(5):
        m.add("laptop", T0 + 10 + k, 0.5, 0.5, 12.0, False)  # the link is good there now
    s = m.stats("laptop", (0, 0))
    assert (s.low_mbps, s.lost_fraction, s.count) == (12.0, 0.0, 5)


def test_old_observations_age_out():
    m = filled(LinkMapParams(max_age_s=3600.0))
    m.add("laptop", T0 + 5000, 2.5, 3.5, 1.0, False)
    m.age_out(T0 + 3600 + 4.5)      # keeps t >= T0 + 4.5: cell (2, 3) has 5 + 1 left
    assert m.stats("laptop", (2, 3)).count == 6
    assert m.stats("laptop", (4, 3)) is None
    assert m.scales() == ["laptop"]


def test_an_observation_needs_a_place_and_a_bandwidth_unless_lost():
    m = LinkMap()
    with pytest.raises(ValueError):
        m.add("laptop", T0, float("nan"), 1.0, 3.0, False)
    with pytest.raises(ValueError):
        m.add("laptop", T0, 1.0, 1.0, float("nan"), False)


def test_saved_and_loaded_back_it_is_the_same_map(tmp_path):
    m = filled()
    path = str(tmp_path / "link_map.yaml")
    m.save(path)
    assert os.listdir(tmp_path) == ["link_map.yaml"]     # the temporary file renamed
    loaded = load_link_map(path)
    for cell in ((2, 3), (4, 3)):
        assert loaded.stats("laptop", cell) == m.stats("laptop", cell)
    with open(path) as f:
        data = yaml.safe_load(f)
    assert (data["format"], data["version"], data["frame_id"], data["resolution"]) == \
        ("anyscale_link_map", 1, "map", 1.0)
    assert data["scales"]["laptop"][0]["cell"] == [2, 3]
    assert data["scales"]["laptop"][0]["observations"][0] == [T0, 2.5, 3.5, 20.0, 0]


def test_a_file_of_another_resolution_is_put_on_this_grid(tmp_path):
    path = str(tmp_path / "m.yaml")
    filled().save(path)
    half = load_link_map(path, LinkMapParams(resolution_m=0.5))
    assert half.stats("laptop", (5, 7)).count == 10      # (2.5, 3.5) at 0.5 m
    assert half.stats("laptop", (8, 7)).lost_fraction == 1.0


def test_loading_ages_the_map(tmp_path):
    path = str(tmp_path / "m.yaml")
    filled().save(path)
    assert load_link_map(path, now=T0 + 7 * 86400 + 100).scales() == []


@pytest.mark.parametrize("content, says", [
    (None, "no such file"),
    ("{", "not YAML"),
    ("- 1\n- 2\n", "expected a mapping, got list"),
    ("format: something_else\n", "format: expected 'anyscale_link_map'"),
    ("format: anyscale_link_map\nversion: 2\n", "version: expected 1, got 2"),
    ("format: anyscale_link_map\nversion: 1\nframe_id: odom\n",
     "frame_id: the map is in 'odom', expected 'map'"),
    ("format: anyscale_link_map\nversion: 1\nframe_id: map\nresolution: 0\n",
     "resolution: expected a number > 0, got 0"),
    ("format: anyscale_link_map\nversion: 1\nframe_id: map\nresolution: 1\nscales: 3\n",
     "scales: expected a mapping of scale names, got int"),
    ("format: anyscale_link_map\nversion: 1\nframe_id: map\nresolution: 1\n"
     "scales: {laptop: [{cell: [0, 0], observations: [[1, 2, 3, -4, 0]]}]}\n",
     "scales.laptop[0].observations[0]: expected [t, x, y, mbps >= 0, lost 0|1], got "
     "[1, 2, 3, -4, 0]"),
    ("format: anyscale_link_map\nversion: 1\nframe_id: map\nresolution: 1\n"
     "scales: {laptop: [{cell: [0, 0], observations: [[1, 2, .nan, 4, 0]]}]}\n",
     "scales.laptop[0].observations[0]"),
    ("format: anyscale_link_map\nversion: 1\nframe_id: map\nresolution: 1\n"
     "scales: {laptop: [[1, 2]]}\n", "scales.laptop[0]: expected {cell"),
])
def test_a_missing_or_corrupt_file_names_itself_and_what_was_wrong(tmp_path, content, says):
    path = str(tmp_path / "link_map.yaml")
    if content is not None:
        with open(path, "w") as f:
            f.write(content)
    with pytest.raises(LinkMapError) as e:
        load_link_map(path)
    assert str(e.value).startswith(path + ": ")
    assert says in str(e.value)


def test_a_file_that_is_not_text_is_an_error(tmp_path):
    path = str(tmp_path / "link_map.yaml")
    with open(path, "wb") as f:
        f.write(b"\xff\xfe\x00binary")
    with pytest.raises(LinkMapError, match="link_map.yaml: "):
        load_link_map(path)
