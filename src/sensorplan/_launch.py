"""The console script's entry point: the command line, and a quiet Ctrl-C while it loads.

``sensorplan`` (and ``python -m sensorplan``) start here rather than in
:mod:`sensorplan.cli`, so that a Ctrl-C pressed while the command line's modules are still
being imported ends with the same one line and exit status as later (130), not with a
traceback of the import.
"""

from __future__ import annotations

import os
import sys
from collections.abc import MutableMapping

from .errors import ConfigError, error_line


#: numpy's switch for transparent huge pages, read when numpy is imported.
HUGEPAGE = "NUMPY_MADVISE_HUGEPAGE"


def numpy_defaults(environ: MutableMapping[str, str]) -> None:
    """The command line's numpy settings, unless the user set them: no transparent huge
    pages for large arrays (``NUMPY_MADVISE_HUGEPAGE=0``).

    numpy asks the kernel for 2 MiB pages for every array of 4 MiB or more. On a virtual
    machine whose memory the host backs only when first touched, each such page stalled for
    milliseconds: a large decision's 50 MB of arrays took 0.2-0.35 s in some runs instead of
    0.01 s, with no gain in the others. Read by numpy when it is imported: set here first.

    Raises ConfigError naming the variable when the user's value is not a whole number
    (numpy would fail on import with a bare ValueError).
    """
    value = environ.setdefault(HUGEPAGE, "0")
    try:
        int(value)
    except ValueError:
        raise ConfigError(HUGEPAGE, f"must be 0 (off) or 1 (on), numpy's setting; got "
                          f"{value!r} (or unset it)") from None


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

        from .cli_guards import interrupt

        signal.signal(signal.SIGINT, interrupt)
        from .cli import main as cli_main
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        sys.exit(130)
    try:
        cli_main()
    finally:
        # The command is over: its results are written and its status set. A Ctrl-C or a
        # SIGTERM now could only cut the interpreter's tear-down short (a second or so with
        # the numerical stack loaded) and end the process by the signal, without a word.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


if __name__ == "__main__":  # pragma: no cover
    main()
