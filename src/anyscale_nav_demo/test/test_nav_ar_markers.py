"""Marker rendering (perspective, distance) and cv2.aruco detection round trip."""
import math

import numpy as np
import pytest

from anyscale_nav_demo.ar_markers import (MarkerDetector, PinholeCamera, background, marker_texture,
                                          render, rotation_to_quaternion)

CAM = PinholeCamera()
TEX = {i: marker_texture(i) for i in range(4)}
DET = MarkerDetector(CAM.K, CAM.D, 0.4)


def marker(mid=2, x=2.0, y=0.0, yaw=math.pi):
    return {"id": mid, "x": x, "y": y, "z": 0.4, "yaw": yaw, "size": 0.4}


@pytest.mark.parametrize("cam, expect", [
    ((1.0, 0.0, 0.4, 0.0), (0.0, 0.0, 1.0)),                 # square on, 1 m
    ((-1.0, 0.0, 0.4, 0.0), (0.0, 0.0, 3.0)),                # 3 m
    ((0.0, 0.3, 0.4, 0.2), (0.69, 0.0, 1.90)),               # off to the side, turned
])
def test_round_trip_pose(cam, expect):
    img, drawn = render(CAM, background(CAM), cam, [marker()], TEX)
    assert drawn == [2]
    found = DET.detect(img)
    assert [f[0] for f in found] == [2]
    t = found[0][1]
    assert t == pytest.approx(expect, abs=0.05 + 0.04 * expect[2])


def test_ids_are_distinguished():
    ms = [marker(1, 2.0, 0.4), marker(3, 2.0, -0.4)]
    img, _ = render(CAM, background(CAM), (0.5, 0.0, 0.4, 0.0), ms, TEX)
    assert sorted(f[0] for f in DET.detect(img)) == [1, 3]


def test_not_drawn_from_behind_or_far_or_out_of_view():
    bg = background(CAM)
    assert render(CAM, bg, (3.0, 0.0, 0.4, math.pi), [marker()], TEX)[1] == []   # behind the wall
    assert render(CAM, bg, (-5.0, 0.0, 0.4, 0.0), [marker()], TEX)[1] == []      # 7 m away
    assert render(CAM, bg, (1.0, 0.0, 0.4, math.pi), [marker()], TEX)[1] == []   # looking away
    assert DET.detect(bg) == []


def test_rotation_to_quaternion():
    c, s = math.cos(0.3), math.sin(0.3)
    q = rotation_to_quaternion(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]))
    assert q == pytest.approx((0, 0, math.sin(0.15), math.cos(0.15)))


def test_detector_params_default_keeps_todays_detector():
    d = MarkerDetector(CAM.K, CAM.D, 0.4, {})
    assert d.params.errorCorrectionRate == pytest.approx(0.3)
    assert d.params.adaptiveThreshWinSizeStep == DET.params.adaptiveThreshWinSizeStep


def test_detector_params_finer_threshold_sweep_still_detects():
    # config/testbed_calibration.yaml's sweep (plus a float field given as an int)
    d = MarkerDetector(CAM.K, CAM.D, 0.4, {"adaptiveThreshWinSizeMax": 53,
                                           "adaptiveThreshWinSizeStep": 2,
                                           "adaptiveThreshConstant": 4,
                                           "errorCorrectionRate": 0.2})
    assert d.params.adaptiveThreshWinSizeMax == 53
    assert d.params.adaptiveThreshWinSizeStep == 2
    assert d.params.adaptiveThreshConstant == pytest.approx(4.0)
    assert d.params.errorCorrectionRate == pytest.approx(0.2)
    img, _ = render(CAM, background(CAM), (1.0, 0.0, 0.4, 0.0), [marker()], TEX)
    assert [f[0] for f in d.detect(img)] == [2]


@pytest.mark.parametrize("bad", [{"noSuchField": 1}, {"adaptiveThreshWinSizeStep": 2.5},
                                 {"adaptiveThreshWinSizeStep": "2"}, {"errorCorrectionRate": "x"}])
def test_detector_params_rejects_unknown_or_mistyped(bad):
    with pytest.raises(ValueError):
        MarkerDetector(CAM.K, CAM.D, 0.4, bad)
