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
        subprocess.run([sys.executable, "-c", "from gyro_fmu.fmu.native import build_package; "
                        "build_package()"], cwd=HERE, check=True)
        super().run()


setup(cmdclass={"build_py": BuildNative})
