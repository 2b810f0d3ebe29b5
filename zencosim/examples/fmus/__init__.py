"""An example FMU, a damped oscillator with a coupling to a terminal, built from C sources by ``build.build_fmu``."""
