"""Compiled runtime objects shared between native builds: compile the design-independent C once.

Every native diagnoser FMU compiles the same runtime translation units (``c/fdi_*.c``, which read
no header of the design) with the same compiler and flags; only the glue and the design data
differ. This cache keeps those units' object files, one per

    key = sha256(compiler identity, compile flags, file name, the source's bytes, the bytes of every
                 header it may include)

where the compiler identity is its command (``$CC`` with its options), the resolved executable's
path, size and modification time, its ``--version`` text and the environment variables that move
its include search (``CPATH``, ``C_INCLUDE_PATH``, ``GCC_EXEC_PREFIX``, ``COMPILER_PATH``). A build
links its own units against these objects: the same sources compiled with the same flags, so the
same library as compiling everything in one command (the compiler compiles each unit separately
either way).

Folder: ``$FMU_FDI_NATIVE_CACHE`` (``off``, ``0``, ``none`` or empty: no cache), else
``$XDG_CACHE_HOME/fmu-fdi/native-objects``, else ``~/.cache/fmu-fdi/native-objects`` (created
private, mode 0700). The cache is never required: any failure here (folder not writable, a compiler
error) returns None and the caller compiles every source as without it.

Concurrent builds, in threads or processes: an object is compiled in a private temporary folder
inside the cache and moved to its final name with an atomic rename only after the compiler
succeeded, so a reader sees either no file or a complete one; two builds that miss together both
compile and the second rename replaces an identical file.

Pruning: each change of the runtime's sources, the compiler or its flags adds a set of objects
(five of about 20 KB). A build touches the objects it links (their modification time is their last
use), and a build that compiled keeps the :data:`MAX_OBJECTS` most recently used ones and removes
the rest, with the build folders of builds killed more than :data:`STALE_BUILD_SECONDS` ago. Builds
in other processes lose nothing they need: the objects they link were touched at their start (newer
than anything removed while fewer than ``MAX_OBJECTS`` objects are newer), and an object removed
under a build all the same only makes its link fail, after which it compiles every source itself.
"""
from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

#: environment variable naming the cache folder ("off", "0", "none" or empty: compile every source)
CACHE_ENV = "FMU_FDI_NATIVE_CACHE"
_OFF = ("", "0", "off", "none", "false", "no")
#: environment variables that change which headers or tools the compiler uses
_COMPILER_ENV = ("CPATH", "C_INCLUDE_PATH", "GCC_EXEC_PREFIX", "COMPILER_PATH")
#: objects a pruned cache keeps, the most recently used: a dozen sets of the runtime's units (~1.3 MB)
MAX_OBJECTS = 64
#: a ``.build-*`` folder this old (seconds) belongs to a build that was killed: pruning removes it
STALE_BUILD_SECONDS = 3600.0


def cache_dir() -> Path | None:
    """The object cache folder (see the module docstring), or None when disabled or no home is known."""
    env = os.environ.get(CACHE_ENV)
    if env is not None:
        return None if env.strip().lower() in _OFF else Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME")
    try:
        root = Path(base) if base else Path.home() / ".cache"
    except (RuntimeError, KeyError):  # no home directory: no cache
        return None
    return root / "fmu-fdi" / "native-objects"


@functools.lru_cache(maxsize=8)
def _version_text(exe: str, mtime_ns: int, size: int, cc: tuple[str, ...]) -> str:
    proc = subprocess.run([*cc, "--version"], capture_output=True, text=True, timeout=60)
    if proc.returncode != 0:
        raise OSError(f"{' '.join(cc)} --version exited with {proc.returncode}")
    return proc.stdout


def compiler_identity(cc: list[str]) -> str:
    """Text that changes when the compiler, its options or its include environment change."""
    exe = shutil.which(cc[0])
    if exe is None:
        raise OSError(f"compiler {cc[0]!r} not found")
    real = os.path.realpath(exe)
    st = os.stat(real)
    env = "\n".join(f"{k}={os.environ.get(k, '')}" for k in _COMPILER_ENV)
    return "\n".join([" ".join(cc), real, str(st.st_size), str(st.st_mtime_ns),
                      _version_text(real, st.st_mtime_ns, st.st_size, tuple(cc)), env])


def object_key(identity: str, flags: tuple[str, ...], name: str, source: bytes, headers: dict[str, bytes]) -> str:
    """The cache key of one translation unit (see the module docstring)."""
    h = hashlib.sha256()
    for part in (identity, "\0".join(flags), name):
        h.update(part.encode("utf-8") + b"\0\0")
    h.update(source + b"\0\0")
    for hname in sorted(headers):
        h.update(hname.encode("utf-8") + b"\0" + headers[hname] + b"\0\0")
    return h.hexdigest()


def shared_objects(src: Path, names: tuple[str, ...], headers: tuple[str, ...], cc: list[str],
                   flags: tuple[str, ...]) -> list[Path] | None:
    """Object files of the units ``names`` in ``src`` (which include only ``headers`` of ``src``),
    compiled with ``cc flags -c`` into the cache on a miss; None if the cache cannot serve them."""
    folder = cache_dir()
    if folder is None or not names:
        return None
    try:
        identity = compiler_identity(cc)
        head = {h: (src / h).read_bytes() for h in headers}
        objs = {n: folder / f"{Path(n).stem}-{object_key(identity, flags, n, (src / n).read_bytes(), head)}.o"
                for n in names}
        missing = [n for n, o in objs.items() if not _touched(o)]
        if missing:
            folder.mkdir(parents=True, exist_ok=True, mode=0o700)
            with tempfile.TemporaryDirectory(prefix=".build-", dir=folder) as tmp:
                # one compiler run for every miss; -c writes <stem>.o into the working folder
                proc = subprocess.run([*cc, *flags, "-I", str(src), "-c", *(str(src / n) for n in missing)],
                                      capture_output=True, text=True, timeout=300, cwd=tmp)
                if proc.returncode != 0:
                    return None  # the caller's full compile reports the compiler's message
                for n in missing:
                    os.replace(Path(tmp, f"{Path(n).stem}.o"), objs[n])
            prune(folder, keep=set(objs.values()))
        return [objs[n] for n in names]
    except (OSError, subprocess.SubprocessError):
        return None


def discard(objects: list[Path]) -> None:
    """Remove cached objects that failed to link (best effort; another build may recompile them)."""
    for o in objects:
        try:
            o.unlink()
        except OSError:
            pass


def _touched(obj: Path) -> bool:
    """Whether ``obj`` is in the cache; if so its modification time becomes now (its last use)."""
    try:
        os.utime(obj)
        return True
    except FileNotFoundError:
        return False
    except OSError:  # a cache this user may read but not write: used as it is
        return obj.is_file()


def prune(folder: Path, max_objects: int | None = None, keep=()) -> None:
    """Keep the ``max_objects`` (default :data:`MAX_OBJECTS`) most recently used objects of the cache
    ``folder`` and those in ``keep``; remove the other objects and the build folders older than
    :data:`STALE_BUILD_SECONDS`. Best effort: a file another build removed first is passed over."""
    limit = MAX_OBJECTS if max_objects is None else max_objects
    keep = {Path(k).name for k in keep}
    objects = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    now = time.time()
    for entry in entries:
        try:
            st = entry.stat(follow_symlinks=False)
            if entry.name.endswith(".o") and entry.is_file(follow_symlinks=False):
                objects.append((st.st_mtime_ns, entry.name))
            elif entry.name.startswith(".build-") and entry.is_dir(follow_symlinks=False) \
                    and now - st.st_mtime > STALE_BUILD_SECONDS:
                shutil.rmtree(entry.path, ignore_errors=True)
        except OSError:
            continue
    others = sorted((o for o in objects if o[1] not in keep), reverse=True)  # newest first
    for _, name in others[max(limit - len(keep), 0):]:
        try:
            os.unlink(os.path.join(folder, name))
        except OSError:
            pass
