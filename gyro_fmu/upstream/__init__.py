"""Workarounds of defects in the libraries gyro_fmu depends on, in one place.

Each module names the upstream version and the defect; tests/test_upstream.py holds one
canary per defect that fails once upstream behaves (then the workaround can go).

The pythonfmu flavour's workarounds live with that flavour (gyro_fmu/pythonfmu/):

- pythonfmu 0.7.0 frees its interpreter guard twice at process exit, so a C host
  crashes after its run: `gyro_fmu.pythonfmu.upstream_exit`
  (canary `test_pythonfmu_still_aborts_a_c_host_at_exit`).
- pythonfmu 0.7.0 cuts "file://" off the resource URI and decodes nothing, so a folder
  with a non-ASCII letter or one of ' $ + , # % ? * [ ] is not found: `python_loader.c`,
  decoded_uri, in gyro_fmu/pythonfmu/ (canary
  `test_pythonfmu_still_takes_the_uri_undecoded`).
- pythonfmu 0.7.0 returns fmi2OK from every setter, maps an exception to fmi2Fatal and
  answers fmi2Terminated = true after any fmi2Discard: `python_loader.c` with
  `gyro_fmu.pythonfmu.upstream_status` (the slave's line to it) and
  gyro_fmu.pythonfmu.slave's guarded callbacks
  (canary `test_pythonfmu_still_answers_terminated_after_a_discard`).

Here, those of the other libraries:

- fmpy 0.3.32 keeps one process-global pointer behind its logger proxy, so a run with
  its own logger leaves the default callbacks calling freed memory: `fmpy_logger`
  (canary `test_fmpy_still_has_one_global_logger_proxy`).
- fmpy 0.3.32's `create_plotly_figure` (behind `plot_result`) rescales the time column of
  the array it is given, in place (to ms for a run under 1 s): examples/read_results.py
  hands it a copy (canary `test_fmpy_still_rescales_the_time_it_plots`).
- Pillow 13.0's `Image.save` (matplotlib's PNG writer) closes the file it opened only on
  an Exception, so a Ctrl-C inside it leaves the file open: `gyro_fmu.outputs.save_figure`
  opens the file itself (canary `test_pillow_still_leaks_its_file_on_an_interrupt`).
- libcosimpy 0.0.6's `time_series_real_samples` drops a sample when step 0 is asked for:
  `libcosim_samples` (canary `test_libcosimpy_still_drops_a_sample`).
- fmu-manipulation-toolbox 2.0's container runtime fails the container when an embedded
  FMU warns at fmi2ExitInitializationMode: `fmu_container` names it before the run
  (canary `test_fmu_container_still_fails_on_an_init_warning`).

They matter only for the pythonfmu flavour (built on request), fmpy's default callbacks
and the SSP run on libcosim: the native FMUs need none of them.
"""
