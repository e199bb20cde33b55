"""Small helpers of the test bed that its tests and benches share: per-process layouts and
waiting with a deadline (no root needed)."""
import itertools

from anyscale_core.polling import wait_for

from anyscale_testbed.two_scale_testbed import TwoScaleLayout, process_layout


def test_a_process_layout_is_its_own_and_fits_interface_names():
    layout = process_layout("asagt", "10.213.77", pid=4194304)     # the largest Linux pid
    default = TwoScaleLayout()
    names = {e.namespace for e in layout.ends} | {e.interface for e in layout.ends}
    assert len(names) == 4
    assert not names & ({e.namespace for e in default.ends} | {e.interface for e in default.ends})
    assert all(len(e.interface) <= 15 for e in layout.ends)          # IFNAMSIZ - 1
    assert [e.address for e in layout.ends] == ["10.213.77.1", "10.213.77.2"]
    assert [e.scale for e in layout.ends] == ["robot", "laptop"]


def test_wait_for_returns_the_first_truthy_value_or_the_last_after_the_deadline():
    calls = itertools.count()
    assert wait_for(lambda: next(calls) >= 3 and "ready", 5.0, 0.001) == "ready"
    assert wait_for(lambda: [], 0.05, 0.01) == []
