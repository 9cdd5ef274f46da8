"""What the command line guards against around its commands: signals, unwritable outputs,
numeric warnings, a bad environment, and figures of runs whose estimates blew up.

Kept apart from :mod:`sensorplan.cli.app` (the commands themselves) and as light to import:
only the standard library at import time.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from .._compiled.threads import ENV as THREADS_ENV
from .._compiled.threads import parse_threads
from ..errors import ConfigError

#: Environment variables the command line checks before it runs a command: name -> the
#: values it may have.
ENVIRONMENT = {"SENSORPLAN_BACKEND": ("numba", "numpy"), "SENSORPLAN_AOT": ("0", "1")}


def check_environment() -> None:
    """Refuse (ConfigError naming the variable) an environment variable of
    :data:`ENVIRONMENT` set to a value it cannot have."""
    for name, allowed in ENVIRONMENT.items():
        value = os.environ.get(name)
        if value is not None and value not in allowed:
            raise ConfigError(name, f"unknown value {value!r} of this environment variable; "
                              f"choose from {', '.join(allowed)} (or unset it)")
    value = os.environ.get(THREADS_ENV)
    if value is not None:
        parse_threads(value)
    # numba refuses a thread count below 1 when it is imported, wherever that happens
    # (other values it cannot read, it ignores).
    threads = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    if threads.lstrip("+-").isdigit() and int(threads) < 1:
        raise ConfigError("NUMBA_NUM_THREADS", f"must be a number of threads >= 1 (numba's), "
                          f"got {threads!r} (or unset it)")
    quiet_matplotlib_dirs()


def _could_write(path: str) -> bool:
    """Whether ``path`` is, or could be made, a directory this process can write in (looked
    up without creating anything)."""
    probe = path
    while not os.path.lexists(probe):
        parent = os.path.dirname(probe)
        if parent == probe:
            return False
        probe = parent
    return os.path.isdir(probe) and os.access(probe, os.W_OK)


def quiet_matplotlib_dirs() -> None:
    """Give matplotlib a private configuration directory when its usual ones cannot be
    written (a read-only home): matplotlib would make a temporary one anyway, but with two
    warning lines on stderr at every figure, and a new font cache each time."""
    import sys
    import tempfile

    if os.environ.get("MPLCONFIGDIR") or not sys.platform.startswith(("linux", "freebsd")):
        return
    home = os.path.expanduser("~")
    usual = [os.path.join(os.environ.get(var) or os.path.join(home, sub), "matplotlib")
             for var, sub in (("XDG_CONFIG_HOME", ".config"), ("XDG_CACHE_HOME", ".cache"))]
    if all(_could_write(p) for p in usual):
        return
    private = os.path.join(tempfile.gettempdir(), f"sensorplan-matplotlib-{os.getuid()}")
    try:
        os.makedirs(private, mode=0o700, exist_ok=True)
        st = os.lstat(private)
    except OSError:
        return                          # matplotlib's own fallback, warnings and all
    if os.path.isdir(private) and not os.path.islink(private) and st.st_uid == os.getuid() \
            and os.access(private, os.W_OK):
        os.environ["MPLCONFIGDIR"] = private


@contextmanager
def quiet_numerics(debug_env: str) -> Iterator[None]:
    """Floating-point RuntimeWarnings (overflow, invalid value) stay off stderr: results
    are checked where they matter, and stderr holds only the one error line on failure.
    Worker processes inherit the filter (``PYTHONWARNINGS``); setting ``debug_env`` shows
    them again."""
    import warnings

    if os.environ.get(debug_env):
        yield
        return
    saved = os.environ.get("PYTHONWARNINGS")
    extra = "ignore::RuntimeWarning"
    os.environ["PYTHONWARNINGS"] = f"{saved},{extra}" if saved else extra
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            yield
    finally:
        if saved is None:
            os.environ.pop("PYTHONWARNINGS", None)
        else:
            os.environ["PYTHONWARNINGS"] = saved


def handle(signum: int, handler: Any) -> Any:
    """Install ``handler`` for ``signum`` unless the signal is ignored; return the previous
    disposition (None where signals are not this thread's to set).

    A signal this process was started with ignored stays ignored, as the Unix convention
    (and Python's own Ctrl-C handling) has it: a shell script runs its background jobs with
    Ctrl-C ignored, so that a Ctrl-C meant for the script does not stop them."""
    import signal

    try:
        if signal.getsignal(signum) == signal.SIG_IGN:
            return signal.SIG_IGN
        return signal.signal(signum, handler)
    except ValueError:                     # not the main thread: signals are not ours
        return None


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is, like Ctrl-C's KeyboardInterrupt."""


class Sigterm:
    """While active, SIGTERM (``kill``, ``timeout``, a batch system) unwinds the command as
    Ctrl-C does (:class:`Terminated`): workers are stopped and finished work is kept.
    ``fired`` tells whether it came."""

    def __init__(self) -> None:
        self.fired = False
        self._previous: Any = None

    def __enter__(self) -> Sigterm:
        import signal

        def stop(signum: int, frame: Any) -> None:
            self.fired = True
            raise Terminated

        self._previous = handle(signal.SIGTERM, stop)
        return self

    def __exit__(self, *exc: object) -> None:
        import signal

        if self._previous not in (None, signal.SIG_IGN):
            signal.signal(signal.SIGTERM, self._previous)


def guard_paths(command: Any) -> Any:
    """Check every path argument and option of ``command``'s subcommands as it is parsed: a
    name the system cannot even look up (too long, a directory without permission on the
    way) is a usage error naming the option, not an internal error wherever it is first
    used. Missing files and directories stay the commands' own business."""
    import errno

    import typer

    def check(ctx: Any, param: Any, value: Any, then: Any = None) -> Any:
        if isinstance(value, Path):
            try:
                os.stat(value)
            except OSError as exc:
                if exc.errno not in (errno.ENOENT, errno.ENOTDIR):
                    raise typer.BadParameter(f"{value}: {exc.strerror or exc}",
                                             param=param) from None
        return value if then is None else then(ctx, param, value)

    for sub in getattr(command, "commands", {}).values():
        for param in sub.params:
            if getattr(getattr(param, "type_descriptor", None), "annotation", None) is Path:
                then = param.callback
                param.callback = (check if then is None else
                                  lambda c, p, v, then=then: check(c, p, v, then))
    return command


@contextmanager
def writing(where: Path | None = None, field: str = "--out") -> Iterator[None]:
    """An output file that cannot be written (a full disk, a directory in its place) is a
    :class:`ConfigError` naming ``field`` and the file (else ``where``)."""
    from ..config.files import write_failed

    try:
        yield
    except OSError as exc:
        raise write_failed(exc, field, where) from None


def plot_drawable(episode: Any, scenario: Any, path: Path) -> None:
    """``plot_episode`` of what can be drawn: covariances and fields of view far larger than
    the map are capped first (:mod:`sensorplan.figures.caps`), so a run whose covariances grew
    huge, or a radar reaching far beyond the map, is drawn at once instead of hanging the
    renderer."""
    from ..figures.caps import drawable, drawable_scenario
    from ..figures.run import plot_episode

    plot_episode(drawable(episode, scenario.world), drawable_scenario(scenario), path)


def animate_drawable(episode: Any, scenario: Any, path: Path) -> Path:
    """``animate_episode`` of what can be drawn, capped as in :func:`plot_drawable`; the
    animation's path."""
    from ..figures.animation import animate_episode
    from ..figures.caps import drawable, drawable_scenario

    return Path(animate_episode(drawable(episode, scenario.world),
                                drawable_scenario(scenario), path))


def lands_unraisable(frame: Any) -> bool:
    """Whether an exception raised by a signal handler in ``frame`` would be lost, or would
    break the code it lands in. True when anywhere on the stack there is

    * a ``__del__`` finalizer: CPython runs it where no exception can propagate, prints
      ``Exception ignored in ...`` with a traceback, and goes on;
    * an import in progress (the import system's frames): the import lock's weakref
      callback runs where no exception can propagate, and a module's top-level code may
      call C code that drops them. An import is over in well under a second;
    * the Python code of numba, llvmlite or scipy, which run Python from C code that drops
      exceptions. numba loads a cached kernel through llvmlite's object-cache callbacks,
      ctypes callbacks: an exception there is printed and dropped, and LLVM goes on with a
      buffer that was never filled (the process crashed); elsewhere in numba an interrupt
      could leave a dispatcher with an exception set (``SystemError``). scipy's Sobol
      generator reads its tables in a Cython function that drops exceptions: an interrupt
      there left them unfilled and the run failed later. Each of these steps takes
      milliseconds (one kernel's compilation at worst);
    * the standard library's ``concurrent.futures``, whose Python code takes its futures'
      and executor's locks in ``__enter__`` methods and loops: an exception landing between
      taking a lock and the ``with`` block that releases it leaves the lock held, and the
      executor's management thread (joined when the interpreter exits) waits on it for
      ever: a study stopped by SIGTERM once hung there. A study waits in it at most
      0.2 s at a time (:mod:`sensorplan.study.execution`).
    """
    roots = _callback_roots()
    while frame is not None:
        code = getattr(frame, "f_code", None)
        if code is not None:
            name, file = code.co_name, code.co_filename
            if name == "__del__" or file.startswith("<frozen importlib"):
                return True
            if roots and file.startswith(roots):
                return True
        frame = getattr(frame, "f_back", None)
    return False


def _callback_roots() -> tuple[str, ...]:
    """The directories of ``concurrent.futures`` and of numba, llvmlite and scipy where
    loaded (a package that is not loaded runs no code; this never imports one)."""
    roots = []
    for name in ("concurrent.futures", "numba", "llvmlite", "scipy"):
        module = sys.modules.get(name)
        file = getattr(module, "__file__", None)
        if file:
            roots.append(os.path.dirname(file) + os.sep)
    return tuple(roots)


def deliver_later(signum: int) -> None:
    """Deliver ``signum`` to this process's handler again in 10 ms, from a helper thread:
    by then the callback has returned (else the handler defers once more). Not at once: a
    signal raised here would run its handler here, still inside the callback."""
    import _thread
    import threading

    timer = threading.Timer(0.01, _thread.interrupt_main, args=(signum,))
    timer.daemon = True
    timer.start()


def interrupt(signum: int, frame: Any) -> None:
    """SIGINT handler while the command line starts: KeyboardInterrupt, except where it
    would be lost (:func:`lands_unraisable`)."""
    if lands_unraisable(frame):
        deliver_later(signum)
        return
    raise KeyboardInterrupt


class Stopped(Exception):
    """A command that was interrupted and has said so on stderr; ``code`` is its exit
    status (130 for Ctrl-C, 143 for SIGTERM). An exception and not ``typer.Exit``, so that
    the entry point can tell it from an interruption nobody reported."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


class Signals:
    """While active (the whole of a command): Ctrl-C raises KeyboardInterrupt as usual and
    SIGTERM raises :class:`Terminated`; ``received`` is the last one (``"INT"``, ``"TERM"``
    or None), so that the entry point can report an interruption that typer turned into a
    bare exit status 130. A signal the process was started with ignored stays ignored
    (:func:`handle`)."""

    def __init__(self) -> None:
        self.received: str | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> Signals:
        import signal

        def interrupt(signum: int, frame: Any) -> None:
            if lands_unraisable(frame):        # it would be printed and lost: not there
                deliver_later(signum)
                return
            self.received = "INT"
            raise KeyboardInterrupt

        def terminate(signum: int, frame: Any) -> None:
            if lands_unraisable(frame):
                deliver_later(signum)
                return
            self.received = "TERM"
            raise Terminated

        for sig, handler in ((signal.SIGINT, interrupt), (signal.SIGTERM, terminate)):
            previous = handle(sig, handler)
            if previous not in (None, signal.SIG_IGN):
                self._previous[sig] = previous
        return self

    def __exit__(self, *exc: object) -> None:
        import signal

        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


def check_finite(result: Any) -> None:
    """A planner's result with a non-finite number is a defect: never printed as a plan."""
    import numpy as np

    values = [result.potential, *np.ravel(result.information), *np.ravel(result.headings)]
    if not np.all(np.isfinite(values)):
        raise RuntimeError(f"planner {result.planner!r} returned non-finite values "
                           f"(potential {result.potential}); this is a bug: please report it "
                           "with the input file")


def usage_error_class() -> type[BaseException]:
    """The class of command-line usage errors."""
    import typer

    # typer raises click's UsageError (vendored in recent typer, the click package in
    # older ones); reach it through the public BadParameter instead of a private import.
    return next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")


def usage_line(exc: Any, argv: Sequence[str] = ()) -> tuple[str, str]:
    """(field, message) of a command-line usage error (``argv``: the command line, to
    name an extra argument whole)."""
    param = getattr(exc, "param", None)
    if param is not None:
        opts = [o for o in getattr(param, "opts", []) if o.startswith("--")]
        name = getattr(param, "metavar", None) or (param.name or "argument").upper()
        field = opts[0] if opts else name
        # A missing argument or option carries no message of its own.
        return field, _conversion_message(exc) or getattr(exc, "message", "") or "is required"
    option = getattr(exc, "option_name", None)
    if option:
        message = exc.format_message()
        prefix = f"No such option: {option}"
        if message.startswith(prefix):
            message = "no such option" + message[len(prefix):]
        return option, message
    extra = _extra_argument(exc, argv)
    if extra is not None:
        return extra
    return "usage", exc.format_message()


def _conversion_message(exc: Any) -> str | None:
    """The package's words for an option value typer could not convert (typer converts with
    pydantic and passes its message on: "Input should be a valid integer, ..."): "must be
    an integer, got 'x'", as a file's value is told; None when it is no such error."""
    from ..limits import type_error

    errors = getattr(exc.__context__, "errors", None)
    if not callable(errors):
        return None
    try:
        err = errors()[0]
    except Exception:  # noqa: BLE001 - not pydantic's error: keep typer's own message
        return None
    kind = str(err.get("type", "")).split("_")[0]
    tp = {"int": int, "float": float, "bool": bool}.get(kind)
    if tp is not None and "input" in err:
        return type_error(tp, err["input"])
    return str(err.get("msg", "")).replace("Input should be", "must be") or None


def _extra_argument(exc: Any, argv: Sequence[str]) -> tuple[str, str] | None:
    """(field, message) of an argument beyond the command's one file (``plan a.json
    b.json``, or ``simulate FILE --gate false``, where the flag takes no value): the
    argument, and for a word that reads as a flag's value, the flag's hint."""
    import re

    from ..config.simulate import BOOLEAN_WORDS

    match = re.match(r"Got unexpected extra arguments?(?:\(s\))? \((.*)\)$",
                     exc.format_message())
    if match is None:
        return None
    listed = match.group(1)          # the extra arguments, joined by spaces
    whole = [a for a in argv if listed == a or listed.startswith(a + " ")]
    first = max(whole, key=len) if whole else listed.split(" ")[0]
    if first.lower() in BOOLEAN_WORDS:
        return first, (f"unexpected extra argument (a flag such as --gate takes no value: "
                       f"write --gate or --no-gate, not --gate {first})")
    command = getattr(getattr(exc, "ctx", None), "info_name", None)
    return first, "unexpected extra argument" + (f" ({command} takes one file)"
                                                  if command else "")
