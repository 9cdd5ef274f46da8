"""The ``sensorplan`` command line: typer app, options, console, signals (no library import)."""
