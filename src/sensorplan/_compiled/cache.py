"""Where numba caches the compiled kernels, and what happens when nowhere is writable.

numba caches the just-in-time kernels on disk (``cache=True``) in the first writable place
of: ``NUMBA_CACHE_DIR`` if set, the package's own ``__pycache__`` directory, the user's
cache directory (``~/.cache/numba`` on Linux). When none is writable (a read-only install
and a read-only home), numba would refuse with a traceback; :func:`ensure_cache`, run when
numba is loaded and before any kernel is compiled (:func:`sensorplan._compiled.jit.activate`), then
caches in a private directory under the system's temporary directory, and when even that
fails compiles without a cache. Either way it says so in one line on stderr, and child
processes (study workers, agents) inherit the choice through ``NUMBA_CACHE_DIR``. The
ahead-of-time kernels (:mod:`sensorplan._compiled.aot`) live in the same places.
"""

from __future__ import annotations

import os
import stat
import sys
import tempfile

#: The notice's prefix, on stderr.
NOTICE = "note: "
#: The package's directory: numba caches each kernel in the ``__pycache__`` beside its module.
PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _writable(path: str) -> bool:
    """Whether ``path`` is (or can be made) a directory this process can write in."""
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
        return True
    except OSError:
        return False


def private_path(base: str, prefix: str = "sensorplan-numba") -> str:
    """``base/<prefix>-<uid>``: this user's directory under a shared one (``/tmp``)."""
    return os.path.join(base, f"{prefix}-{os.getuid() if hasattr(os, 'getuid') else 0}")


def is_private(path: str) -> bool:
    """Whether ``path`` is a directory (not a link) of this user that nobody else can write
    in: only then may compiled code be loaded from it."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    mine = not hasattr(os, "getuid") or st.st_uid == os.getuid()
    return stat.S_ISDIR(st.st_mode) and mine and not st.st_mode & 0o022


def _private_dir(base: str, prefix: str = "sensorplan-numba") -> str | None:
    """:func:`private_path` when it is (or can be made) private, else a fresh directory
    under ``base``; None if ``base`` is not writable."""
    path = private_path(base, prefix)
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
        if is_private(path) and _writable(path):
            return path
        return tempfile.mkdtemp(prefix=f"{prefix}-", dir=base)
    except OSError:
        return None


def user_cache_dir() -> str:
    """The user's cache directory for numba (``~/.cache/numba`` on Linux), as numba's
    ``AppDirs`` names it, without importing numba."""
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA", os.path.expanduser("~"))
        return os.path.join(base, "numba", "Cache")
    if sys.platform == "darwin":
        return os.path.expanduser("~/Library/Caches/numba")
    base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return os.path.join(base, "numba")


def cache_places() -> list[str]:
    """Where numba would cache this package's kernels, in numba's order of preference."""
    cache_dir = os.environ.get("NUMBA_CACHE_DIR", "")
    if "numba" in sys.modules:
        cache_dir = getattr(sys.modules["numba"].config, "CACHE_DIR", "") or cache_dir
    places = [cache_dir] if cache_dir else []
    places.append(os.path.join(PACKAGE_DIR, "__pycache__"))
    places.append(user_cache_dir())
    return places


def ensure_cache() -> str | None:
    """Make sure numba can cache the kernels (see the module docstring).

    Returns
    -------
    str or None   the notice written to stderr, or None when a usual place is writable
    """
    import numba

    places = cache_places()
    if any(_writable(p) for p in places):
        return None
    fallback = _private_dir(tempfile.gettempdir())
    if fallback is not None:
        setattr(numba.config, "CACHE_DIR", fallback)  # noqa: B010 - numba.config is untyped
        os.environ["NUMBA_CACHE_DIR"] = fallback
        notice = (f"{NOTICE}cannot write numba's kernel cache ({', '.join(places)}); caching "
                  f"the compiled kernels in {fallback} (set NUMBA_CACHE_DIR to choose)")
    else:
        # No directory at all: compile in every process. Dispatchers then keep numba's
        # null cache instead of failing on cache=True.
        numba.core.dispatcher.Dispatcher.enable_caching = lambda self: None  # type: ignore
        notice = (f"{NOTICE}no writable directory for numba's kernel cache ({', '.join(places)}, "
                  f"{tempfile.gettempdir()}); compiling the kernels in this process, without "
                  "a cache (set NUMBA_CACHE_DIR to a writable directory)")
    sys.stderr.write(notice + "\n")
    sys.stderr.flush()
    return notice


def _has_kernels(root: str, mine: bool) -> bool:
    """Whether ``root`` holds a numba cache index of this package (``mine``: every index
    under ``root`` is this package's)."""
    for dirpath, _, files in os.walk(root):
        if (mine or "sensorplan" in dirpath) and any(f.endswith(".nbi") for f in files):
            return True
    return False


def first_run_notice() -> str | None:
    """Say once, on stderr, that the kernels are being compiled when no cached kernel of this
    package exists yet (a fresh clone or install): the first command then spends about a
    minute compiling before its own work, which would otherwise look like a hang.

    Returns
    -------
    str or None   the notice written, or None when kernels are cached (or already noted)
    """
    if os.environ.get("SENSORPLAN_FIRST_RUN_NOTED"):
        return None
    cache_dir = os.environ.get("NUMBA_CACHE_DIR", "")
    if "numba" in sys.modules:
        cache_dir = getattr(sys.modules["numba"].config, "CACHE_DIR", "") or cache_dir
    if cache_dir:
        cold = not _has_kernels(cache_dir, mine=False)
    else:
        cold = not (_has_kernels(PACKAGE_DIR, mine=True)
                    or _has_kernels(cache_places()[-1], mine=False))
    os.environ["SENSORPLAN_FIRST_RUN_NOTED"] = "1"      # children (workers) stay quiet
    if not cold:
        return None
    notice = (f"{NOTICE}first run: compiling the numerical kernels once (about a minute); "
              "they are cached for every later run")
    sys.stderr.write(notice + "\n")
    sys.stderr.flush()
    return notice


__all__ = ["NOTICE", "cache_places", "ensure_cache", "first_run_notice", "user_cache_dir"]
