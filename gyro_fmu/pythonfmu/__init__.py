"""The pythonfmu flavour, in one place: FMUs whose slave is a Python class over the same C
core (built on request: `gyro-fmu build --flavour pythonfmu`; needs the `pythonfmu` extra).

- slave.py: the adapter base class every fmu_src/<Model>.py slave builds on (declared
  variables, guarded callbacks, FMU states through state.py); slaves.py finds and loads
  those slave sources;
- shipping.py: which gyro_fmu modules such an FMU carries in its resources/;
  shipped_copies.py: many such FMUs, each with its own copy, in one process (the import
  hook, installed only by a copy inside an FMU);
- loader.py and python_loader.c: our C loader in front of pythonfmu's binary (a C host
  needs no settings), python_env.py: what it needs of this Python;
- upstream_exit.py, upstream_status.py: the workarounds of pythonfmu 0.7.0's defects
  (gyro_fmu/upstream/__init__.py lists them with their canaries).

Nothing below the FMU build (gyro_fmu.fmu.build) and the doctor imports this package; the
native FMUs and `import gyro_fmu` never do.
"""
