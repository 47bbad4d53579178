"""Every native FMU's declaration, by model identifier: the one registry the build, the
reference results and the doctor read (their variables, reference inputs, doctor check),
whatever the flavour an FMU was built in."""

from __future__ import annotations

from ..estimation.interface import OBSERVER
from ..model.interfaces import PHYSICS_INTERFACES, FmuInterface
from ..model.selfcal_interfaces import SELFCAL_INTERFACES
from ..sensor.interface import SENSOR
from ..sensor.platform import PLATFORM

#: The native FMUs, by model identifier: the physics', the observer's, the
#: self-calibration's, the sensor's and its system example's declarations.
NATIVE_INTERFACES: dict[str, FmuInterface] = {**PHYSICS_INTERFACES,
                                              OBSERVER.identifier: OBSERVER,
                                              **SELFCAL_INTERFACES,
                                              SENSOR.identifier: SENSOR,
                                              PLATFORM.identifier: PLATFORM}
