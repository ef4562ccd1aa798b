import pytest

from trackjam.config import load_scenario
from trackjam.radio.antenna import AntennaModel
from trackjam.simulation.build import antenna_model


@pytest.fixture(scope="session")
def antenna() -> AntennaModel:
    return antenna_model(load_scenario("paper-fig3"))

