"""``python -m sensorplan``: the same command line as the ``sensorplan`` script."""

from .cli.launch import main

if __name__ == "__main__":
    main()
