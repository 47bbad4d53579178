"""Build every gyro_fmu FMU into models/ (same as `gyro-fmu build`)."""

from gyro_fmu.cli import main

if __name__ == "__main__":
    raise SystemExit(main(["build"]))
