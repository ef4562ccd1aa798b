"""trackjam: a team of pursuer drones cooperatively tracks a rogue drone in 3D and radio-jams
it, without jamming each other (Papaioannou, Kolios, Ellinas, IROS 2021, and beyond)."""

__version__ = "0.1.0"

__all__ = ["Scenario", "load_scenario", "simulate", "__version__"]


def __getattr__(name: str):
    # Imported when first asked for, so that `import trackjam` (and `trackjam --help`) stays light;
    # the scenario's names come through simulation/build.py, the one module of a run that reads it.
    if name in ("Scenario", "load_scenario"):
        from trackjam.simulation import build

        return getattr(build, name)
    if name == "simulate":
        from trackjam.simulation.loop import simulate

        return simulate
    raise AttributeError(name)
