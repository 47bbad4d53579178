#!/usr/bin/env bash
# Check the native FMUs against the reference results they carry (fmi-ls-ref), as a
# step of your own CI would: exit 0 when every output of every FMU is in its band.
#
#     bash examples/validate_in_ci.sh [DEST]
set -euo pipefail
dest=${1:-fmus}
gyro-fmu fmus --dest "$dest" --fmi 2          # the FMI 2.0 FMUs into DEST
gyro-fmu validate "$dest"/*.fmu
