"""Examples that ship with zencosim: FMUs built from C sources, a Python model."""
