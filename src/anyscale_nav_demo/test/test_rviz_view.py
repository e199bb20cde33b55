"""rviz_view (no ROS, no screen): each world's map extent, the view that frames it, and the
package's rviz config with only that view's X, Y and Scale changed."""
import os

import pytest
import yaml

from anyscale_nav_demo.rviz_view import (RENDER_PANEL_PX, View, ViewError, framed_config,
                                         framing, map_extent)

PKG = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
CONFIG = os.path.join(PKG, "rviz", "nav_demo.rviz")


def current_view(text):
    return yaml.safe_load(text)["Visualization Manager"]["Views"]["Current"]


@pytest.mark.parametrize("world, size_m", [("office_floor", 40.55), ("small_loop", 12.8)])
def test_each_worlds_view_is_centred_on_its_map_and_shows_all_of_it(world, size_m):
    extent = map_extent(os.path.join(PKG, "maps", world + ".yaml"))
    assert extent == pytest.approx((0.0, 0.0, size_m, size_m))
    view = framing(extent)
    assert (view.x, view.y) == pytest.approx((size_m / 2, size_m / 2))
    shown_m = min(RENDER_PANEL_PX) / view.scale
    assert size_m < shown_m < 1.15 * size_m      # all of it, and not lost in a corner


def test_a_wide_map_is_fitted_by_its_width_and_a_rotated_origin_counts(tmp_path):
    assert framing((-10.0, 0.0, 90.0, 10.0), (900, 700), 1.0).scale == pytest.approx(9.0)
    (tmp_path / "m.pgm").write_bytes(b"P5\n4 2\n255\n" + bytes([254] * 8))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 1.0\n"
                                     "origin: [1.0, 2.0, 1.5707963]\nnegate: 0\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    x0, y0, x1, y1 = map_extent(str(tmp_path / "m.yaml"))
    assert (x0, y0, x1, y1) == pytest.approx((-1.0, 2.0, 1.0, 6.0), abs=1e-6)


def test_the_config_keeps_every_byte_but_the_views_x_y_and_scale():
    with open(CONFIG) as f:
        text = f.read()
    framed = framed_config(text, View(6.4, 6.4, 50.888))
    assert current_view(framed)["Class"] == "rviz/TopDownOrtho"
    assert (current_view(framed)["X"], current_view(framed)["Y"],
            current_view(framed)["Scale"]) == (6.4, 6.4, 50.888)
    changed = [(a, b) for a, b in zip(text.splitlines(), framed.splitlines()) if a != b]
    assert [b.strip().split(":")[0] for _, b in changed] == ["Scale", "X", "Y"]
    assert len(text.splitlines()) == len(framed.splitlines())


def test_a_config_without_a_top_down_view_is_refused_naming_it():
    with open(CONFIG) as f:
        text = f.read()
    orbit = text.replace("rviz/TopDownOrtho", "rviz/Orbit")
    with pytest.raises(ViewError, match="my.rviz: the current view is 'rviz/Orbit'"):
        framed_config(orbit, View(0, 0, 1), "my.rviz")
    with pytest.raises(ViewError, match="no 'Views: Current:' block"):
        framed_config("Panels: []\n", View(0, 0, 1))
    with pytest.raises(ViewError, match="no single 'Scale:'"):
        framed_config(text.replace("      Scale: 20\n", ""), View(0, 0, 1))


def test_an_empty_extent_is_refused():
    with pytest.raises(ValueError, match="positive width and height"):
        framing((1.0, 1.0, 1.0, 5.0))
