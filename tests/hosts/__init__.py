"""Test-only pieces of the FMU-hosting tests: stand-in slaves, their Python reference, the C
host and scenario scripts run in their own processes (see docs/fmu-hosts.md)."""
