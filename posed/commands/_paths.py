"""What the commands share about their input and output files.

* :func:`refuse_same_file`: an output that is one of the inputs (same path, a symlink to it, a hard link of it)
  is refused before anything is opened for writing (exit 2, a usage error): ``posed fit a.jsonl -o a.jsonl``
  would otherwise truncate the recording before reading it.
* :class:`Output`: a command's output file or standard output. Every write, flush and close failure becomes
  one :class:`OutputError`; :meth:`Output.failed` says what went wrong in one line (``disk full at PATH: No
  space left on device; free space or write elsewhere``), removes the partial file the command created
  (never standard output, a device or a FIFO) and gives the exit status: 74 (EX_IOERR), or 141 quietly for a
  closed pipe on standard output, as ``head`` makes other Unix tools end.
* :func:`sniff`: what a file looks like from its first bytes (an image, a video, a landmark recording, binary
  data), so a command handed the wrong file says which command takes it.
"""

from __future__ import annotations

import errno
import os
import stat
import sys
from pathlib import Path

EX_USAGE = 2
EX_IOERR = 74           # sysexits.h: an error while doing I/O on a file
EX_PIPE = 141           # 128 + SIGPIPE: what a shell reports for a tool whose reader went away

DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


# -- an output that is an input ---------------------------------------------------------------------------------

def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether the paths name one file: equal once resolved (symlinks followed), or, when both exist, the same
    inode on the same device (a hard link, a bind mount)."""
    try:
        if Path(a).resolve() == Path(b).resolve():
            return True
    except (OSError, RuntimeError):             # a symlink loop: fall through to samefile
        pass
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def is_stdout(path: str | os.PathLike | None) -> bool:
    return path is None or str(path) in ("", "-")


def refuse_same_file(cmd: str, output: str | os.PathLike | None,
                     inputs: list[tuple[str, str | os.PathLike | None]]) -> int | None:
    """``EX_USAGE`` after saying so on stderr when ``output`` is the same file as one of ``inputs`` (pairs of
    what the input is and its path; None paths are skipped); None when it is not (or the output is stdout)."""
    if is_stdout(output):
        return None
    for what, path in inputs:
        if path is None or is_stdout(path):
            continue
        if same_file(output, path):
            print(f"{cmd}: the output {output} is the same file as the {what} {path}: writing it would destroy "
                  f"the {what} before it is read; nothing was written: choose another output file (-o)",
                  file=sys.stderr, flush=True)
            return EX_USAGE
    return None


def config_inputs(args) -> list[tuple[str, str | None]]:
    """The config file named by ``--config`` (an input every command that reads the config has)."""
    return [("config file", getattr(args, "config", None))]


# -- writing ----------------------------------------------------------------------------------------------------

def _stdout_target() -> str:
    """Where standard output goes (``/dev/full``, a file's path), when the system says so."""
    try:
        target = os.readlink("/proc/self/fd/1")
    except OSError:
        return ""
    return target if target.startswith("/") else ""


def stdout_name() -> str:
    """``standard output``, with where it goes when the system says so: ``standard output (/dev/full)``."""
    target = _stdout_target()
    return f"standard output ({target})" if target else "standard output"


def silence_stdout() -> None:
    """Point file descriptor 1 at /dev/null, so that what Python still holds in the buffer of ``sys.stdout``
    is dropped at exit instead of failing again ("Exception ignored ... BrokenPipeError")."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass


def write_problem(name: str, exc: OSError) -> str:
    """One line saying why ``name`` could not be written and what to do about it."""
    reason = exc.strerror or str(exc)
    code = exc.errno
    if code in DISK_FULL:
        return f"disk full at {name}: {reason}; free space or write elsewhere"
    if code == errno.EROFS:
        return f"cannot write {name}: {reason} (a read-only file system); write elsewhere"
    if code in (errno.EACCES, errno.EPERM):
        return f"cannot write {name}: {reason}; write where you may, or run as a user who may write there"
    if code == errno.ENOENT:
        parent = Path(name).parent
        return f"cannot write {name}: the folder {parent} does not exist; create it or write elsewhere"
    if code == errno.ENOTDIR:
        return f"cannot write {name}: a part of the path is a file, not a folder; write elsewhere"
    if code == errno.EISDIR:
        return f"cannot write {name}: it is a folder; give a file name, e.g. {Path(name) / 'out'}"
    return f"cannot write {name}: {reason}"


def file_write_failed(cmd: str, path: str | os.PathLike, exc: OSError, status: int = EX_USAGE) -> int:
    """Report that writing the file ``path`` (written by another module in one go) failed; a partial regular
    file is removed. Exit status EX_IOERR for a full disk, else ``status``."""
    removed = ""
    try:
        if exc.errno in DISK_FULL and stat.S_ISREG(os.lstat(path).st_mode):
            os.unlink(path)
            removed = "; the partial file was removed"
    except OSError:
        pass
    print(f"{cmd}: {write_problem(str(path), exc)}{removed}", file=sys.stderr, flush=True)
    return EX_IOERR if exc.errno in DISK_FULL else status


class OutputError(Exception):
    """Writing an :class:`Output` failed (``exc``: the OSError); :meth:`Output.failed` reports it."""

    def __init__(self, output: Output, exc: OSError) -> None:
        super().__init__(str(exc))
        self.output = output
        self.exc = exc


class Output:
    """A command's output: the file ``path``, or standard output for None, ``""`` or ``"-"``.

    ``open`` raises OSError (the caller reports it with :meth:`open_failed`); ``write``, ``flush`` and ``close``
    raise :class:`OutputError`. File-like enough for ``print(..., file=out)`` and ``csv.writer(out)``."""

    def __init__(self, cmd: str, path: str | os.PathLike | None, binary: bool = False, newline: str | None = None):
        self.cmd = cmd
        self.path = None if is_stdout(path) else str(path)
        self.binary = binary
        self.newline = newline
        self.fh = None
        self._regular = False           # the file opened is a regular file: removed when writing it fails

    @property
    def name(self) -> str:
        return self.path if self.path is not None else stdout_name()

    def open(self, mkdir: bool = False) -> Output:
        if self.path is None:
            self.fh = sys.stdout.buffer if self.binary else sys.stdout
            return self
        if mkdir:
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        if self.binary:
            self.fh = open(self.path, "wb")
        else:
            self.fh = open(self.path, "w", encoding="utf-8", newline=self.newline)
        try:
            self._regular = stat.S_ISREG(os.fstat(self.fh.fileno()).st_mode)
        except OSError:
            self._regular = False
        return self

    def open_failed(self, exc: OSError, status: int = EX_USAGE) -> int:
        """Report an ``open`` failure; the exit status is ``status``, EX_IOERR for a full disk."""
        print(f"{self.cmd}: {write_problem(self.path or self.name, exc)}", file=sys.stderr, flush=True)
        return EX_IOERR if exc.errno in DISK_FULL else status

    def write(self, data) -> int:
        try:
            return self.fh.write(data)
        except OSError as exc:
            raise OutputError(self, exc) from exc

    def flush(self) -> None:
        try:
            self.fh.flush()
        except OSError as exc:
            raise OutputError(self, exc) from exc

    def close(self) -> None:
        """Flush standard output, or close the file (idempotent)."""
        if self.fh is None:
            return
        fh, self.fh = self.fh, None
        try:
            if self.path is None:
                fh.flush()
            else:
                fh.close()
        except OSError as exc:
            self.fh = fh
            raise OutputError(self, exc) from exc

    def discard(self) -> None:
        """Close without reporting anything (after an error, or when the command gives up); a file is kept."""
        fh, self.fh = self.fh, None
        if fh is None or self.path is None:
            return
        try:
            fh.close()
        except OSError:
            pass

    def failed(self, exc: OSError) -> int:
        """Report a write failure in one line, remove the partial file, and give the exit status."""
        fh, self.fh = self.fh, None
        name = self.name                   # before standard output is pointed at /dev/null
        if self.path is None:
            silence_stdout()               # what is still buffered must not fail again at exit
            if isinstance(exc, BrokenPipeError):
                return EX_PIPE             # the reader went away (| head): quietly, as Unix tools end
        elif fh is not None:
            try:
                fh.close()
            except OSError:
                pass
        removed = ""
        if self.path is not None and self._regular:
            try:
                os.unlink(self.path)
                removed = "; the partial file was removed"
            except OSError:
                pass
        print(f"{self.cmd}: {write_problem(name, exc)}{removed}", file=sys.stderr, flush=True)
        return EX_IOERR

    def __enter__(self) -> Output:
        return self

    def __exit__(self, *exc: object) -> None:
        self.discard()


# -- what a file is ---------------------------------------------------------------------------------------------

_MAGIC = (
    (b"\xff\xd8\xff", "image", "JPEG"),
    (b"\x89PNG\r\n\x1a\n", "image", "PNG"),
    (b"GIF87a", "image", "GIF"),
    (b"GIF89a", "image", "GIF"),
    (b"BM", "image", "BMP"),
    (b"II*\x00", "image", "TIFF"),
    (b"MM\x00*", "image", "TIFF"),
    (b"\x1a\x45\xdf\xa3", "video", "Matroska/WebM"),
    (b"SQLite format 3\x00", "database", "SQLite"),
    (b"#ROSBAG", "video", "RealSense .bag"),
)


def sniff(path: str | os.PathLike) -> tuple[str, str]:
    """(kind, what) of a file from its first bytes: kind is ``image``, ``video``, ``database``,
    ``landmarks`` (a landmark recording's header), ``binary`` (not UTF-8 text), ``text`` or ``unreadable``;
    ``what`` names the format (``JPEG``) or is empty."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return "unreadable", ""
    for magic, kind, what in _MAGIC:
        if head.startswith(magic):
            return kind, what
    if head[:4] == b"RIFF" and head[8:12] in (b"WEBP", b"AVI "):
        return ("image", "WebP") if head[8:12] == b"WEBP" else ("video", "AVI")
    if head[4:8] == b"ftyp":
        return "video", "MP4/MOV"
    first = head.split(b"\n", 1)[0]
    if first.lstrip().startswith(b"{") and b'"posed.landmarks"' in first:
        return "landmarks", "landmark recording"
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:       # not a multi-byte character cut by the 4096-byte window
            return "binary", ""
    return "text", ""
