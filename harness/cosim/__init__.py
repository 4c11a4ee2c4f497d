"""Co-simulation of a planned profile through the FMU chain: the system (SSP), the masters
(native and Python), the FMU driver, the recorders, the run metrics and one run (`run_case`)."""
