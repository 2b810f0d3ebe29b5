"""Models zencosim does not implement itself: FMUs (through fmpy) and users' Python model classes.

``model.py`` makes either a zencosim subsystem model; ``component.py`` says what zencosim knows of a
component; ``fmu.py`` and ``python_model.py`` load and run the two kinds; ``points.py`` maps coupling
roles onto a component's variables. docs/models.md is the user's guide.
"""
