"""The console script's entry point: the command line, and a quiet Ctrl-C while it loads.

``sensorplan`` (and ``python -m sensorplan``) start here rather than in
:mod:`sensorplan.cli`, so that a Ctrl-C pressed while the command line's modules are still
being imported ends with the same one line and exit status as later (130), not with a
traceback of the import.
"""

from __future__ import annotations

import sys


def main() -> None:
    try:
        import signal
        import threading  # noqa: F401 - loaded before a handler may need it (deliver_later)

        from .cli_guards import interrupt

        signal.signal(signal.SIGINT, interrupt)
        from .cli import main as cli_main
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        sys.exit(130)
    cli_main()


if __name__ == "__main__":  # pragma: no cover
    main()
