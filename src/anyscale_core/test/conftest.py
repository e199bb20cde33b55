"""Fixtures for anyscale_core's tests."""
from hypothesis import settings
import pytest
import yaml

from anyscale_core.allocators import make_allocator
from anyscale_core.characterisation import characterise
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams
from anyscale_core.model_loader import load_model

from core_test_data import TESTBED
from decision_reports import reports

settings.register_profile("anyscale", deadline=None, max_examples=60, derandomize=True)
settings.load_profile("anyscale")


@pytest.fixture
def testbed_path():
    return TESTBED


@pytest.fixture
def testbed_dict():
    with open(TESTBED) as f:
        return yaml.safe_load(f)


@pytest.fixture
def testbed():
    return load_model(TESTBED)


@pytest.fixture
def testbed_ch(testbed):
    return characterise(testbed)


@pytest.fixture
def engine(testbed_ch):
    """The decision engine on the test bed with the paper's allocator, no bandwidth hold and no
    start-up grace, after it started every node on the robot."""
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, startup_grace_s=0.0))
    e.adopt_or_start(reports(0.0), 0.0)
    return e
