"""Which scales' status subscription the decision node makes anew (silent_scales)."""
from anyscale_core.decision_types import silent_scales


def test_a_scale_never_heard_from_is_silent_once_the_subscription_is_old_enough():
    # The laptop agent came up with the link down: its status never came.
    assert silent_scales(["laptop"], {}, subscribed_at=100.0, now=105.5, after_s=5.0) == ["laptop"]
    assert silent_scales(["laptop"], {}, subscribed_at=100.0, now=104.0, after_s=5.0) == []


def test_a_scale_is_silent_from_its_last_status_or_the_last_renewal_whichever_is_later():
    received = {"laptop": 100.0, "server": 110.0}
    assert silent_scales(["laptop", "server"], received, subscribed_at=90.0, now=112.0,
                         after_s=5.0) == ["laptop"]
    # Renewed 2 s ago: the new subscription gets its own 5 s to connect.
    assert silent_scales(["laptop", "server"], received, subscribed_at=110.0, now=112.0,
                         after_s=5.0) == []
