"""The console script's entry point: the command line, a quiet Ctrl-C while it loads, and
the process's memory settings (:mod:`sensorplan.memory`).

``sensorplan`` (and ``python -m sensorplan``) start here rather than in
:mod:`sensorplan.cli.app`, so that a Ctrl-C pressed while the command line's modules are still
being imported ends with the same one line and exit status as later (130), not with a
traceback of the import (a command started with Ctrl-C ignored, as a shell script starts its
background jobs, keeps ignoring it); and so that numpy's and glibc's memory settings
(:func:`numpy_defaults`, :func:`malloc_defaults`) are made before numpy loads.
"""

from __future__ import annotations

import os
import sys

from ..errors import ConfigError, error_line
from ..memory import malloc_defaults, numpy_defaults


def main() -> None:
    try:
        numpy_defaults(os.environ)
    except ConfigError as exc:
        if not {"--help", "-h", "--version"} & set(sys.argv[1:]):   # they need no numpy
            sys.stderr.write(error_line(exc.field, exc.message) + "\n")
            sys.exit(2)
    try:
        import signal
        import threading  # noqa: F401 - loaded before a handler may need it (deliver_later)

        from .guards import handle, interrupt

        handle(signal.SIGINT, interrupt)    # left ignored where started ignored (a background job)
        malloc_defaults(os.environ)              # before numpy allocates anything
        from .app import main as cli_main
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        sys.exit(130)
    try:
        cli_main()
    except KeyboardInterrupt:
        # A Ctrl-C in the instants before the command's own handling starts (it catches
        # every later one): the same line, never a traceback.
        sys.stderr.write("error: interrupted\n")
        sys.exit(130)
    finally:
        # The command is over: its results are written and its status set. A Ctrl-C or a
        # SIGTERM now could only cut the interpreter's tear-down short (a second or so with
        # the numerical stack loaded) and end the process by the signal, without a word.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


if __name__ == "__main__":  # pragma: no cover
    main()
