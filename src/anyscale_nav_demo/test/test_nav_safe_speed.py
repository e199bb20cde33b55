"""Safe-speed rule: 5 Hz corrections -> 0.4 m/s, 2 Hz -> 0.2 m/s, none -> stop."""
import pytest

from anyscale_nav_demo.safe_speed import CorrectionMonitor, safe_speed_limit


def limit_for(rate_hz, now_offset=0.0):
    m = CorrectionMonitor(window=3.0)
    t = 0.0
    while t < 5.0:
        m.add(t)
        t += 1.0 / rate_hz
    now = m.times[-1] + now_offset
    return safe_speed_limit(m.rate(), m.age(now), 0.4, 0.1, 2.0)


def test_paper_speeds():
    assert limit_for(5.0) == pytest.approx(0.4)
    assert limit_for(2.0) == pytest.approx(0.2)
    assert limit_for(10.0) == pytest.approx(0.4)    # capped at the robot's top speed


def test_overdue_correction_slows_then_stops():
    assert limit_for(5.0, now_offset=0.5) == pytest.approx(0.2)   # 0.5 s without one
    assert limit_for(5.0, now_offset=1.0) == pytest.approx(0.1)
    assert limit_for(5.0, now_offset=2.5) == 0.0                  # past the tolerance


def test_no_corrections_no_motion():
    m = CorrectionMonitor()
    assert safe_speed_limit(m.rate(), m.age(10.0), 0.4, 0.1, 2.0) == 0.0
    m.add(1.0)
    assert safe_speed_limit(m.rate(), m.age(1.1), 0.4, 0.1, 2.0) == 0.0   # one is not a rate


def test_window_forgets_old_rate():
    m = CorrectionMonitor(window=2.0)
    for k in range(50):
        m.add(k * 0.1)                 # 10 Hz
    for k in range(1, 6):
        m.add(4.9 + k * 0.5)           # then 2 Hz
    assert m.rate() == pytest.approx(2.0, rel=0.01)
