"""map_server semantics of the map loader: thresholds, negate, origin, row order, errors."""
import numpy as np
import pytest

from anyscale_nav_demo.occupancy_map import MapError, OccupancyMap, load_map, save_map


def write_pgm(path, img, binary=True):
    h, w = img.shape
    if binary:
        path.write_bytes(b"P5\n# comment\n%d %d\n255\n" % (w, h) + img.astype(np.uint8).tobytes())
    else:
        body = " ".join(str(int(v)) for v in img.ravel())
        path.write_text("P2\n%d %d\n255\n%s\n" % (w, h, body))


def write_yaml(path, image="m.pgm", **over):
    meta = dict(image=image, resolution=0.1, origin=[-1.0, 2.0, 0.0], negate=0,
                occupied_thresh=0.65, free_thresh=0.196)
    meta.update(over)
    path.write_text("\n".join("%s: %s" % (k, v) for k, v in meta.items()) + "\n")


@pytest.fixture
def grey():
    # top row: black (occupied), white (free), grey 205 (unknown); bottom row all white
    return np.array([[0, 254, 205], [254, 254, 254]])


@pytest.mark.parametrize("binary", [True, False])
def test_thresholds_and_row_order(tmp_path, grey, binary):
    write_pgm(tmp_path / "m.pgm", grey, binary)
    write_yaml(tmp_path / "m.yaml")
    m = load_map(str(tmp_path / "m.yaml"))
    # image's top row is the grid's last row (max y)
    assert m.data.tolist() == [[0, 0, 0], [100, 0, -1]]
    assert m.resolution == pytest.approx(0.1)
    assert m.origin == (-1.0, 2.0, 0.0)


def test_negate_inverts(tmp_path, grey):
    write_pgm(tmp_path / "m.pgm", grey)
    write_yaml(tmp_path / "m.yaml", negate=1)
    m = load_map(str(tmp_path / "m.yaml"))
    # 205 inverted is 50: p = (255 - 50) / 255 = 0.80 > occupied_thresh
    assert m.data[1].tolist() == [0, 100, 100]


def test_world_to_cell_uses_origin(tmp_path, grey):
    write_pgm(tmp_path / "m.pgm", grey)
    write_yaml(tmp_path / "m.yaml")
    m = load_map(str(tmp_path / "m.yaml"))
    col, row = m.world_to_cell(-0.95, 2.15)
    assert (int(col), int(row)) == (0, 1)
    assert m.is_occupied_at(np.array([-0.95]), np.array([2.15]))[0]
    assert m.is_occupied_at(np.array([-5.0]), np.array([0.0]))[0]   # off the map


def test_save_then_load_round_trip(tmp_path):
    data = np.array([[0, 100, -1], [100, 0, 0]], dtype=np.int8)
    save_map(OccupancyMap(data, 0.05, (1.0, 2.0, 0.0)), str(tmp_path / "r.yaml"))
    m = load_map(str(tmp_path / "r.yaml"))
    assert m.data.tolist() == data.tolist()
    assert m.origin == (1.0, 2.0, 0.0)


@pytest.mark.parametrize("case, expect", [
    ("missing_yaml", "map YAML not found"),
    ("missing_image", "map image not found"),
    ("bad_yaml", "malformed YAML"),
    ("no_resolution", "missing key 'resolution'"),
    ("bad_origin", "key 'origin'"),
    ("bad_thresholds", "free_thresh < occupied_thresh"),
    ("bad_magic", "not a PGM image"),
    ("truncated", "PGM data truncated"),
])
def test_bad_input_names_file_and_problem(tmp_path, grey, case, expect):
    yaml_path = tmp_path / "m.yaml"
    write_pgm(tmp_path / "m.pgm", grey)
    write_yaml(yaml_path)
    if case == "missing_yaml":
        yaml_path = tmp_path / "nope.yaml"
    elif case == "missing_image":
        write_yaml(yaml_path, image="other.pgm")
    elif case == "bad_yaml":
        yaml_path.write_text("image: [unclosed\n")
    elif case == "no_resolution":
        yaml_path.write_text("image: m.pgm\norigin: [0, 0, 0]\n")
    elif case == "bad_origin":
        write_yaml(yaml_path, origin="[1, 2]")
    elif case == "bad_thresholds":
        write_yaml(yaml_path, free_thresh=0.9)
    elif case == "bad_magic":
        (tmp_path / "m.pgm").write_bytes(b"P6\n3 2\n255\n" + bytes(18))
    elif case == "truncated":
        (tmp_path / "m.pgm").write_bytes(b"P5\n3 2\n255\n" + bytes(4))
    with pytest.raises(MapError) as e:
        load_map(str(yaml_path))
    assert expect in str(e.value)
    assert ".yaml" in str(e.value) or ".pgm" in str(e.value)
