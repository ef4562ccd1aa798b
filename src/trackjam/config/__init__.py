"""The scenario configuration: the model (``model.py``) and how a scenario is read
(``loading.py``). Everything is importable from ``trackjam.config``."""

from trackjam.config.loading import (
    apply_overrides,
    load_scenario,
    load_scenario_data,
    preset_names,
    scenario_to_dict,
    scenario_to_yaml,
    set_dotted,
    validate_scenario,
)
from trackjam.config.model import (
    Agents,
    Antenna,
    Area,
    Control,
    Cue,
    Filter,
    Fusion,
    Metrics,
    Response,
    Scenario,
    Sensor,
    Stochastic,
    Target,
)

__all__ = [
    "Agents", "Antenna", "Area", "Control", "Cue", "Filter", "Fusion", "Metrics", "Response",
    "Scenario", "Sensor", "Stochastic", "Target", "apply_overrides", "load_scenario",
    "load_scenario_data", "preset_names", "scenario_to_dict", "scenario_to_yaml", "set_dotted",
    "validate_scenario",
]
