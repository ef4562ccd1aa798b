"""trackjam: a team of pursuer drones cooperatively tracks a rogue drone in 3D and radio-jams
it, without jamming each other (Papaioannou, Kolios, Ellinas, IROS 2021, and beyond)."""

from trackjam.config import Scenario, load_scenario

__version__ = "0.1.0"

__all__ = ["Scenario", "load_scenario", "simulate", "__version__"]


def __getattr__(name: str):
    # simulate pulls in numba-compiled code: import it only when asked for
    if name == "simulate":
        from trackjam.simulation.loop import simulate

        return simulate
    raise AttributeError(name)
