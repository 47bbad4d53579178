"""The gyroscope as a sensor: GyroSensor.fmu's declaration (the drive, the plant and the
observer of US 2011/0314910 A1 in one FMU at a fixed internal step, then a readout), the
same chain computed in-process as its independent check, and its datasheet."""
