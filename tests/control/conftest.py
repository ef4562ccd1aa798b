import pytest

from trackjam.config import load_scenario
from trackjam.radio.antenna import AntennaModel


@pytest.fixture(scope="session")
def antenna() -> AntennaModel:
    return AntennaModel.from_scenario(load_scenario("paper-fig3"))

