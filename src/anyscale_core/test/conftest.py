"""Fixtures for anyscale_core's tests."""
from hypothesis import settings
import pytest
import yaml

from anyscale_core.characterisation import characterise
from anyscale_core.model_loader import load_model

from core_test_data import TESTBED

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
