"""Build the FMUs: `python build_fmu.py` puts every FMU into models/ (same as `gyro-fmu
build`); `python build_fmu.py --native` recompiles the C core and the native FMUs into the
package (what `pip install` does; needs ziglang)."""

import sys

if __name__ == "__main__":
    if sys.argv[1:] == ["--native"]:
        from gyro_fmu.fmu.package import build_package

        build_package(force=True)
        raise SystemExit(0)
    from gyro_fmu.cli import main

    raise SystemExit(main(["build", *sys.argv[1:]]))
