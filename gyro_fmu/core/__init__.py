"""The C core (fmu_src/core/) as the Python library calls it: the same compiled code that
steps inside every native FMU. `library.core()` loads it; `library.CORE_FUNCTIONS` lists
the signatures."""
