"""The build of the native parts: `pip install` (wheel, sdist or editable) compiles the C
core and the native FMUs for every platform with zig cc (gyro_fmu.fmu.native) before the
package files are collected. Everything else is in pyproject.toml."""

import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


class BuildNative(build_py):
    def run(self) -> None:
        subprocess.run([sys.executable, "-c", "from gyro_fmu.fmu.package import build_package; "
                        "build_package()"], cwd=HERE, check=True)
        super().run()


# The folders the native build fills are listed as packages in pyproject.toml (setuptools
# warns about each package-data folder that is not); egg_info runs before the build and
# refuses a listed package whose folder does not exist, so they are made here first.
for folder in ("gyro_fmu/core/lib", "gyro_fmu/fmus/fmi2", "gyro_fmu/fmus/fmi3"):
    (HERE / folder).mkdir(parents=True, exist_ok=True)

setup(cmdclass={"build_py": BuildNative})
