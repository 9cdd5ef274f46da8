"""The console script's entry point: the command line, and a quiet Ctrl-C while it loads.

``sensorplan`` (and ``python -m sensorplan``) start here rather than in
:mod:`sensorplan.cli`, so that a Ctrl-C pressed while the command line's modules are still
being imported ends with the same one line and exit status as later (130), not with a
traceback of the import.
"""

from __future__ import annotations

import sys

TYPE_CHECKING = False                    # typing is not needed before the guard (see main)
if TYPE_CHECKING:  # pragma: no cover
    from typing import Any


def lands_unraisable(frame: Any) -> bool:
    """Whether an exception raised by a signal handler in ``frame`` would be lost: CPython
    runs an import lock's weakref callback (and ``__del__`` finalizers) where no exception
    can propagate, prints ``Exception ignored in ...`` with a traceback, and goes on. True
    when such a callback is anywhere on the stack (the exception would end there)."""
    while frame is not None:
        code = getattr(frame, "f_code", None)
        if code is not None and (code.co_name == "__del__" or (
                code.co_name == "cb" and code.co_filename.startswith("<frozen importlib"))):
            return True
        frame = getattr(frame, "f_back", None)
    return False


def deliver_later(signum: int) -> None:
    """Deliver ``signum`` to this process's handler again in 10 ms, from a helper thread:
    by then the callback has returned (else the handler defers once more). Not at once: a
    signal raised here would run its handler here, still inside the callback."""
    import _thread
    import threading

    timer = threading.Timer(0.01, _thread.interrupt_main, args=(signum,))
    timer.daemon = True
    timer.start()


def _interrupt(signum: int, frame: Any) -> None:
    if lands_unraisable(frame):
        deliver_later(signum)
        return
    raise KeyboardInterrupt


def main() -> None:
    try:
        import signal
        import threading  # noqa: F401 - loaded before a handler may need it (deliver_later)

        signal.signal(signal.SIGINT, _interrupt)
        from .cli import main as cli_main
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        sys.exit(130)
    cli_main()


if __name__ == "__main__":  # pragma: no cover
    main()
