"""The FMU slave adapters, one module per FMU (installed as gyro_fmu.fmu_src)."""
