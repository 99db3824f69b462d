"""The ``posed`` command line. Each subcommand is a module of :mod:`posed.commands` with a
``register(subparsers)`` function; ``posed bench NAME`` runs ``bench.commands.NAME`` (loaded only then)."""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import pkgutil
import sys

from posed import commands
from posed.commands._paths import EX_IOERR, EX_PIPE, OutputError, silence_stdout, stdout_name, write_problem
from posed.daemon.config import EX_CONFIG
from posed.daemon.config.load import ConfigError


class VersionAction(argparse.Action):
    """``posed --version``: ``posed X.Y.Z`` and, on a second line, the landmark models the daemon runs (converter
    version, mediapipe release, ONNX hashes: ``daemon.version.version_text``; read from the manifest only when
    asked, so no other command pays for it)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from posed.daemon.version import version_text

        print(version_text(), flush=True)
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="posed",
        description="Edge daemon: one camera -> live 3D human pose, joint angles and fall events over Zenoh.",
    )
    parser.add_argument("--version", action=VersionAction, nargs=0,
                        help="show posed's version and the landmark models it runs, and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    return parser


def quiet_opencv() -> None:
    """OpenCV's ``[ WARN:0@...]`` lines and FFmpeg's own messages stay out of the output (posed reports what
    it cannot read itself); set these variables to see them. Before OpenCV loads, and inherited by the
    daemon's stage processes."""
    os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")   # AV_LOG_QUIET


# errors of the file system a command did not catch itself: one line, not a traceback (main)
FILE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.ENOENT, errno.EISDIR)


def main(argv: list[str] | None = None) -> int:
    quiet_opencv()
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status = int(args.func(args) or 0)
        sys.stdout.flush()          # what is still buffered: a full disk must be said here, not at exit
        return status
    except ConfigError as exc:
        print(str(exc), file=sys.stderr)
        print(f"posed: {len(exc.problems)} problem(s) in the configuration; nothing was started", file=sys.stderr)
        return EX_CONFIG
    except KeyboardInterrupt:
        return 130
    except OutputError as exc:              # a command's output that failed and was not reported by it
        return exc.output.failed(exc.exc)
    except BrokenPipeError:                 # the reader of standard output went away (| head): quietly
        silence_stdout()
        return EX_PIPE
    except OSError as exc:                  # the last line of defence: one line naming the file
        if exc.errno not in FILE_ERRNOS:
            raise
        name = exc.filename if exc.filename is not None else stdout_name()
        if exc.filename is None:
            silence_stdout()
        if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS):
            print(f"posed {args.command}: {write_problem(str(name), exc)}", file=sys.stderr)
        else:
            print(f"posed {args.command}: {name}: {exc.strerror or exc}", file=sys.stderr)
        return EX_IOERR


if __name__ == "__main__":
    sys.exit(main())
